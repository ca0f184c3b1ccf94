// loopwire gateway --config FILE [--check] [-v]
// One process owns every line of the configuration and shares it: Modbus TCP clients reach the
// devices through it, their requests queued fairly with each other (docs/DESIGN.md, gateway).
#include <systemd/sd-daemon.h>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/stop_signal.hpp"
#include "gateway/gateway.hpp"

namespace loopwire::app {
namespace {

struct GatewayCommandOptions {
    std::string config;
    bool check = false;
    bool verbose = false;
};

int run_gateway(const GatewayCommandOptions& options, const ProfileOptions& profiles) {
    auto registry = profiles.load();
    if (!registry) return report_error(registry.error());
    auto config = gateway::load_gateway_config(options.config, *registry);
    if (!config) return report_error(config.error());
    if (options.check) {
        fmt::print("{}", gateway::describe_plan(*config));
        return exit_ok;
    }
    StopSignal stop;  // before any thread starts: they inherit the blocked signals
    gateway::GatewayOptions gateway_options;
    gateway_options.log = [](const std::string& line) { fmt::print(stderr, "loopwire: gateway: {}\n", line); };
    if (options.verbose) gateway_options.trace = stderr_trace();
    auto gateway = gateway::Gateway::open(*config, gateway_options);
    if (!gateway) return report_error(gateway.error());
    std::size_t devices = 0;
    for (const auto& line : config->lines) devices += line.devices.size();
    if (config->modbus_tcp.enabled) {
        fmt::print(stderr, "loopwire: gateway: {} line(s), {} device(s); Modbus TCP on {} (listening on port {}); Ctrl-C to stop\n",
                   config->lines.size(), devices, config->modbus_tcp.host, (*gateway)->modbus_tcp_port());
    } else {
        fmt::print(stderr, "loopwire: gateway: {} line(s), {} device(s); Modbus TCP front disabled; Ctrl-C to stop\n",
                   config->lines.size(), devices);
    }
    // Under systemd (Type=notify, packaging/loopwire-gateway.service) the unit is up once the
    // lines and the listener are open; without $NOTIFY_SOCKET these calls do nothing.
    sd_notifyf(0, "READY=1\nSTATUS=serving %zu line(s), %zu device(s)", config->lines.size(), devices);
    auto served = (*gateway)->serve(stop.token());
    sd_notify(0, "STOPPING=1");
    for (const auto& line : (*gateway)->report()) fmt::print(stderr, "loopwire: gateway: {}\n", gateway::describe(line));
    if (!served) return report_error(served.error());
    return exit_ok;
}

}  // namespace

void add_gateway_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<GatewayCommandOptions>();
    auto* command = app.add_subcommand("gateway", "Own the lines of a configuration file and serve them to Modbus TCP clients");
    command->add_option("--config", options->config, "Gateway configuration (TOML): lines, devices, the Modbus TCP front")->required();
    command->add_flag("--check", options->check, "Check the configuration and print the plan (lines, devices, estimated line load); serve nothing");
    command->add_flag("-v,--verbose", options->verbose, "Print every frame on the lines and the front, with timestamps, on stderr");
    command->footer(exit_code_help);
    command->callback([options, &exit_code, &profiles] { exit_code = run_gateway(*options, profiles); });
}

}  // namespace loopwire::app
