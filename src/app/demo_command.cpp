// loopwire demo: the embedded default behind the README's first command. Three simulated
// controllers (AC20 at unit 1, ramp/soak at unit 2, TC10 at unit 3) share one RTU line on a
// virtual bus inside the process; the live monitor polls them there, while the same
// simulators also answer Modbus/TCP on loopback so the commands the demo suggests can be tried
// from another terminal against the very devices on screen.
#include <unistd.h>

#include <thread>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/monitor_output.hpp"
#include "client/monitor_loop.hpp"
#include "client/monitor_names.hpp"
#include "app/simulated_units.hpp"
#include "app/stop_signal.hpp"
#include "client/device_client.hpp"
#include "session/slave.hpp"
#include "transport/tcp.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::app {
namespace {

struct DemoOptions {
    std::string duration;  // empty: until Ctrl-C on a terminal, 5 s otherwise
    double speed = 30.0;
    int port = 1502;
    std::string format;
    bool verbose = false;
};

const std::vector<std::string> demo_devices{"ac20@1", "rampsoak@2", "tc10@3"};

// Set points that make the process move from the first sample on (each model starts cold).
// The AC20 takes writes only in remote (Note 5), so bit 218 goes first.
const std::vector<std::pair<std::string, std::vector<std::string>>> demo_settings{
    {"ac20@1", {"local_remote=remote", "main_set_point=1.00"}},
    {"rampsoak@2", {"set_value=180.0"}},
    {"tc10@3", {"set_point=150"}},
};

void apply_demo_settings(session::Master& master) {
    for (const auto& [address_text, assignments] : demo_settings) {
        auto address = device::parse_device_address(address_text);
        if (!address) continue;
        device::DeviceClient client(master, *address);
        for (const std::string& assignment : assignments) {
            const auto equals = assignment.find('=');
            const device::Parameter* parameter = address->profile->find(assignment.substr(0, equals));
            auto written = parameter ? client.write({{parameter, assignment.substr(equals + 1)}})
                                     : Result<device::WriteReport>(make_error(ErrorKind::usage, "no such parameter"));
            if (!written) fmt::print(stderr, "loopwire demo: could not set {} {}: {}\n", address_text, assignment, written.error().message);
        }
    }
}


Result<std::optional<std::chrono::microseconds>> demo_duration(const DemoOptions& options) {
    if (options.duration.empty()) {
        if (::isatty(STDOUT_FILENO) == 1) return std::optional<std::chrono::microseconds>{};
        return std::optional<std::chrono::microseconds>{std::chrono::seconds(5)};  // scripts, CI: ends by itself
    }
    auto parsed = parse_duration(options.duration, "--duration");
    if (!parsed) return parsed.error();
    return std::optional<std::chrono::microseconds>{*parsed};
}

// Port 1502 when free (the commands shown stay the same from run to run), else any free port.
Result<std::unique_ptr<transport::TcpListener>> demo_listener(int port) {
    auto listener = transport::TcpListener::listen("127.0.0.1", static_cast<std::uint16_t>(port));
    if (listener || port == 0) return listener;
    return transport::TcpListener::listen("127.0.0.1", 0);
}

void print_hint(std::uint16_t port, bool bounded, double speed) {
    const std::string link = fmt::format("tcp://127.0.0.1:{}", port);
    fmt::print(stderr,
               "loopwire demo: an AC20 (unit 1), a ramp/soak controller (unit 2) and a TC10 (unit 3) simulated on one "
               "RTU line, process time x{}.\n"
               "The same simulators answer on {} - try, from another terminal:\n"
               "  loopwire read  --link {} --device tc10@3 PV SP rV\n"
               "  loopwire write --link {} --device tc10@3 SP=200\n"
               "  loopwire read  --link {} --device ac20@1 St.Pn\n"
               "  loopwire dump  --link {} --device rampsoak@2 --output rampsoak.json\n"
               "  loopwire monitor --link {} --device tc10@3 --device rampsoak@2\n"
               "{}\n",
               speed, link, link, link, link, link, link, bounded ? "" : "Ctrl-C stops the demo.");
}

int run_demo(const DemoOptions& options) {
    auto format = monitor_format(options.format, ::isatty(STDOUT_FILENO) == 1);
    if (!format) return report_error(format.error());
    auto duration = demo_duration(options);
    if (!duration) return report_error(duration.error());
    auto link = transport::parse_link_url("rtu:virtual?baud=19200&parity=none");
    if (!link) return report_error(link.error());
    device::SimulationEnvironment environment;
    environment.speed = options.speed;
    // The demo's devices are built-in ones: no profile files needed.
    auto builtins = device::ProfileRegistry::builtins();
    if (!builtins) return report_error(builtins.error());
    auto units = build_simulated_units(*builtins, {}, demo_devices, *link, environment);
    if (!units) return report_error(units.error());
    auto listener = demo_listener(options.port);
    if (!listener) return report_error(listener.error());

    StopSignal stop(*duration);  // before any thread starts, so they inherit the blocked signals
    auto bus = transport::VirtualBus::create(link->serial.baud, 10);
    auto slave_port = bus->attach("simulators");
    session::Slave line_slave(*link, units->units);
    session::Slave tcp_slave(*transport::parse_link_url("tcp://127.0.0.1:0"), units->units);
    std::jthread line_server([&](std::stop_token) { (void)line_slave.serve_stream(*slave_port, stop.token()); });
    std::jthread tcp_server([&](std::stop_token) { (void)tcp_slave.serve_listener(**listener, stop.token()); });

    session::MasterOptions master_options;
    master_options.timeout = std::chrono::milliseconds(500);
    master_options.retries = 1;  // a loaded machine can stretch a frame on the virtual line
    if (options.verbose) master_options.trace = stderr_trace();
    auto master = session::make_serial_master(bus->attach("monitor"), *link, master_options);
    apply_demo_settings(*master);

    print_hint((*listener)->port(), duration->has_value(), options.speed);
    std::vector<device::MonitorTarget> targets;
    for (const std::string& text : demo_devices) {
        auto address = device::parse_device_address(text);
        if (!address) return report_error(address.error());
        targets.push_back(device::MonitorTarget{master.get(), *address, device::default_watch_list(*address->profile)});
    }
    StreamSampleSink sink(stdout, *format);
    device::run_monitor(targets, device::MonitorSettings{}, sink, stop.token());
    stop.request_stop();
    return exit_ok;
}

}  // namespace

void add_demo_command(CLI::App& app, int& exit_code) {
    auto options = std::make_shared<DemoOptions>();
    auto* command = app.add_subcommand("demo", "Simulate an AC20, a ramp/soak controller and a TC10, and watch them live");
    command->add_option("--duration", options->duration, "End by itself after this long (default: until Ctrl-C on a terminal, 5s otherwise)");
    command->add_option("--speed", options->speed, "Process time per real second")->check(CLI::Range(0.001, 100000.0))->capture_default_str();
    command->add_option("--port", options->port, "Loopback TCP port where the same simulators answer (another if busy; 0 = any)")
        ->check(CLI::Range(0, 65535))->capture_default_str();
    command->add_option("--format", options->format, "table, csv or jsonl (default: table on a terminal, jsonl otherwise)");
    command->add_flag("-v,--verbose", options->verbose, "Print every frame on the demo's line, with timestamps, on stderr");
    command->callback([options, &exit_code] { exit_code = run_demo(*options); });
}

}  // namespace loopwire::app
