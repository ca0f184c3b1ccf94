// loopwire gateway --config FILE [--check] [-v], or --print-config
// One process owns every line of the configuration and shares it: Modbus TCP clients reach the
// devices through it, their requests queued fairly with each other (docs/DESIGN.md, gateway).
// SIGHUP re-reads the configuration: a bad one is reported and the running one kept
// (gateway/service.hpp).
#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>

#include <systemd/sd-daemon.h>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/gateway_log.hpp"
#include "app/stop_signal.hpp"
#include "gateway/config_schema.hpp"
#include "gateway/gateway.hpp"
#include "gateway/service.hpp"

namespace loopwire::app {
namespace {

struct GatewayCommandOptions {
    std::string config;
    bool check = false;
    bool verbose = false;
    bool print_config = false;
};

// The gateway's log (app/gateway_log.hpp) as the gateway's parts and its service take it: one
// logger for the command's run, shared by every thread that logs.
gateway::ServiceLog service_log(const std::shared_ptr<spdlog::logger>& logger) {
    gateway::ServiceLog log;
    log.info = [logger](const std::string& line) { log_event(*logger, line); };
    log.warning = [logger](const std::string& line) { logger->warn(line); };
    log.debug = [logger](const std::string& line) { logger->debug(line); };
    log.set_level = [logger](gateway::LogConfig::Level level) { set_log_level(*logger, level); };
    return log;
}

// Every Modbus TCP and HTTP client costs a descriptor, and the default soft limit (1024) is far
// below what the kernel lets the process have (the hard limit). Raised once at start, so that the
// fronts' own bounds ([modbus_tcp] and [http] max_connections), not the soft limit, decide who
// is served. systemd sets both through LimitNOFILE= (packaging/loopwire-gateway.service).
void raise_descriptor_limit(const gateway::GatewayLog& log_debug) {
    rlimit limit{};
    if (::getrlimit(RLIMIT_NOFILE, &limit) != 0) {
        log_debug(fmt::format("open files: the limit cannot be read ({})", std::strerror(errno)));
        return;
    }
    if (limit.rlim_cur >= limit.rlim_max) {
        log_debug(fmt::format("open files: at most {} (already the hard limit)", limit.rlim_cur));
        return;
    }
    const rlim_t before = limit.rlim_cur;
    limit.rlim_cur = limit.rlim_max;
    if (::setrlimit(RLIMIT_NOFILE, &limit) != 0) {
        log_debug(fmt::format("open files: at most {}; raising it to the hard limit {} failed ({})", before, limit.rlim_max,
                              std::strerror(errno)));
        return;
    }
    log_debug(fmt::format("open files: limit raised from {} to the hard limit, {}", before, limit.rlim_max));
}

void announce(const gateway::GatewayLog& log_line, const gateway::GatewayConfig& config, const gateway::Gateway& running) {
    std::size_t devices = 0;
    for (const auto& line : config.lines) devices += line.devices.size();
    if (config.modbus_tcp.enabled) {
        log_line(fmt::format("{} line(s), {} device(s); Modbus TCP on {} (listening on port {}); Ctrl-C to stop",
                             config.lines.size(), devices, config.modbus_tcp.host, running.modbus_tcp_port()));
    } else {
        log_line(fmt::format("{} line(s), {} device(s); Modbus TCP front disabled; Ctrl-C to stop", config.lines.size(), devices));
    }
    if (config.history) log_line(fmt::format("history: recording to {}", config.history->database.string()));
    if (config.http) {
        const bool ipv6 = config.http->host.find(':') != std::string::npos;
        log_line(fmt::format("HTTP API and dashboard on {}://{}{}{}:{}/ (writes {})",
                             config.http->certificate.empty() ? "http" : "https", ipv6 ? "[" : "", config.http->host,
                             ipv6 ? "]" : "", running.http_port(),
                             !config.http->users.empty() ? "by the users of http.users_file"
                             : config.http->token.empty() ? "refused: no http.token_file"
                                                          : "with the token"));
    }
    if (config.opcua) {
        const bool ipv6 = config.opcua->host.find(':') != std::string::npos;
        log_line(fmt::format("OPC UA on opc.tcp://{}{}{}:{} (writes {})", ipv6 ? "[" : "", config.opcua->host, ipv6 ? "]" : "",
                             running.opcua_port(), config.opcua->writes ? "confirmed by the device" : "refused"));
    }
    // Under systemd (Type=notify, packaging/loopwire-gateway.service) the unit is up once the
    // lines and the listener are open; without $NOTIFY_SOCKET these calls do nothing.
    sd_notifyf(0, "READY=1\nSTATUS=serving %zu line(s), %zu device(s)", config.lines.size(), devices);
}

// Under a unit with WatchdogSec= (packaging/loopwire-gateway.service), the engine's loop says
// WATCHDOG=1 every half period, as sd_watchdog_enabled(3) advises: a loop that hangs goes
// silent and systemd restarts the service. Without $WATCHDOG_USEC nothing is sent.
void watch_over(gateway::GatewayOptions& options) {
    std::uint64_t period_us = 0;
    if (sd_watchdog_enabled(0, &period_us) <= 0 || period_us == 0) return;
    options.alive_every = std::max(std::chrono::milliseconds(1),
                                   std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::microseconds(period_us / 2)));
    options.alive = [] { sd_notify(0, "WATCHDOG=1"); };
}

int run_gateway(const GatewayCommandOptions& options, const ProfileOptions& profiles) {
    if (options.print_config) {
        fmt::print("{}", gateway::commented_example_config());
        return exit_ok;
    }
    if (options.config.empty()) {
        return report_error(make_error(ErrorKind::usage, "gateway: --config FILE.toml is required (`loopwire gateway "
                                                         "--print-config > gateway.toml` writes a complete example)"));
    }
    auto registry = profiles.load();
    if (!registry) return report_error(registry.error());
    auto config = gateway::load_gateway_config(options.config, *registry);
    if (!config) return report_error(config.error());
    if (auto ready = gateway::check_environment(*config); !ready) return report_error(ready.error());
    if (options.check) {
        if (auto reached = gateway::check_history_forwarding(*config); !reached) return report_error(reached.error());
        fmt::print("{}", gateway::describe_plan(*config));
        return exit_ok;
    }
    const auto logger = make_gateway_logger();
    const auto log = service_log(logger);
    log.set_level(config->log.level);
    raise_descriptor_limit(log.debug);
    gateway::ConfigReloads reloads(options.config, *registry, log);
    // Before any thread starts. The serving thread takes the signals while it waits.
    StopSignal stop(std::nullopt, [&reloads] { reloads.hangup(); }, StopSignal::Waits::caller);
    gateway::GatewayOptions gateway_options;
    gateway_options.wait_for_stop = [&stop](const std::stop_token& until) { stop.wait(until); };
    gateway_options.log = log.info;
    gateway_options.debug_log = log.debug;
    watch_over(gateway_options);
    if (options.verbose) gateway_options.trace = stderr_trace();
    gateway::ServiceHooks hooks;
    hooks.serving = [&log](const gateway::GatewayConfig& serving, const gateway::Gateway& running) { announce(log.info, serving, running); };
    hooks.reloading = [] { sd_notify(0, "RELOADING=1"); };
    auto served = gateway::serve_with_reloads(std::move(*config), gateway_options, reloads, stop.token(), log, hooks);
    if (!served) return report_error(served.error());
    sd_notify(0, "STOPPING=1");
    return exit_ok;
}

}  // namespace

void add_gateway_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<GatewayCommandOptions>();
    auto* command = app.add_subcommand("gateway", "Own the lines of a configuration file and serve them to Modbus TCP clients");
    auto* config = command->add_option("--config", options->config, "Gateway configuration (TOML): lines, devices, the Modbus TCP front")
        ->type_name("FILE.toml");
    auto* check = command->add_flag("--check", options->check, "Check the configuration and print the plan (lines, devices, estimated line load); serve nothing. "
                                     "Every mistake is said, each at FILE:LINE, then their count");
    command
        ->add_flag("--print-config", options->print_config,
                   "Print a complete configuration with every key, its meaning, bounds and default (man loopwire-gateway.toml)")
        ->excludes(check)
        ->excludes(config);
    command->add_flag("-v,--verbose", options->verbose, "Print every frame on the lines and the front, with timestamps, on stderr");
    command->footer(std::string("SIGTERM or Ctrl-C stops the gateway once the requests it has taken are answered; SIGHUP re-reads "
                                "the configuration (a configuration with errors is reported and the running one kept).\n\n") +
                    exit_code_help);
    command->callback([options, &exit_code, &profiles] { exit_code = run_gateway(*options, profiles); });
}

}  // namespace loopwire::app
