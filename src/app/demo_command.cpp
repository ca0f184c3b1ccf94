// loopwire demo: the embedded default behind the README's first command. The gateway runs on
// its embedded plant: three simulated controllers (AC20 at unit 1, ramp/soak at unit 2, TC10 at
// unit 3) on one virtual 19200-baud RTU line inside the process, polled by the gateway, whose
// samples are shown live, and shared over Modbus TCP and HTTP (the API and the dashboard) on
// loopback, so the commands the demo prints reach the very devices on screen through the
// gateway (docs/DESIGN.md, gateway).
#include <unistd.h>

#include <atomic>
#include <thread>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/monitor_output.hpp"
#include "app/stop_signal.hpp"
#include "client/device_client.hpp"
#include "client/link.hpp"
#include "gateway/gateway.hpp"

namespace loopwire::app {
namespace {

struct DemoOptions {
    std::string duration;  // empty: until Ctrl-C on a terminal, 5 s otherwise
    double speed = 30.0;
    int port = 1502;
    int http_port = 8080;
    std::string format;
    bool verbose = false;
};

// The embedded plant, in the gateway's own configuration language: what `loopwire gateway
// --config` would run for the same plant (examples/plant.toml has a real one).
std::string demo_config(double speed, int port, int http_port) {
    return fmt::format(R"toml(
[[lines]]
name = "plant"
link = "rtu:virtual?baud=19200&parity=none"
timeout = "500ms"
retries = 1            # a loaded machine can stretch a frame on the virtual line
speed = {}

[[lines.devices]]
name = "furnace"
device = "ac20@1"

[[lines.devices]]
name = "kiln"
device = "rampsoak@2"

[[lines.devices]]
name = "oven"
device = "tc10@3"

[modbus_tcp]
listen = "127.0.0.1:{}"

[http]
listen = "127.0.0.1:{}"
)toml", speed, port, http_port);
}

// Set points that make the process move from the first sample on (each model starts cold).
// The AC20 takes writes only in remote (Note 5), so bit 218 goes first.
const std::vector<std::pair<std::string, std::vector<std::string>>> demo_settings{
    {"ac20@1", {"local_remote=remote", "main_set_point=1.00"}},
    {"rampsoak@2", {"set_value=180.0"}},
    {"tc10@3", {"set_point=150"}},
};

// Written through the gateway's Modbus TCP front, as any client would.
void apply_demo_settings(device::Master& master) {
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

// Passes samples on once opened: the live table starts below the hint, not mixed into it.
class SinkOpenedLater final : public device::SampleSink {
public:
    explicit SinkOpenedLater(device::SampleSink& sink) : sink_(sink) {}
    void open() { open_ = true; }
    void write(const device::SampleView& sample) override {
        if (open_) sink_.write(sample);
    }

private:
    device::SampleSink& sink_;
    std::atomic<bool> open_{false};
};

Result<std::optional<std::chrono::microseconds>> demo_duration(const DemoOptions& options) {
    if (options.duration.empty()) {
        if (::isatty(STDOUT_FILENO) == 1) return std::optional<std::chrono::microseconds>{};
        return std::optional<std::chrono::microseconds>{std::chrono::seconds(5)};  // scripts, CI: ends by itself
    }
    auto parsed = parse_duration(options.duration, "--duration");
    if (!parsed) return parsed.error();
    return std::optional<std::chrono::microseconds>{*parsed};
}

Result<gateway::GatewayConfig> demo_gateway_config(double speed, int port, int http_port) {
    auto builtins = device::ProfileRegistry::builtins();  // the demo's devices are built-in ones
    if (!builtins) return builtins.error();
    return gateway::parse_gateway_config(demo_config(speed, port, http_port), "the demo's embedded plant", *builtins);
}

// On ports 1502 and 8080 when free (the commands shown stay the same from run to run), else on
// any free ones.
Result<std::unique_ptr<gateway::Gateway>> open_demo_gateway(const DemoOptions& options, gateway::GatewayOptions gateway_options) {
    const std::pair<int, int> tries[] = {{options.port, options.http_port}, {options.port, 0}, {0, 0}};
    Result<std::unique_ptr<gateway::Gateway>> opened = make_error(ErrorKind::usage, "not opened");
    for (const auto& [port, http_port] : tries) {
        auto config = demo_gateway_config(options.speed, port, http_port);
        if (!config) return config.error();
        opened = gateway::Gateway::open(*config, gateway_options);
        if (opened) return opened;
    }
    return opened;
}

void print_hint(std::uint16_t port, std::uint16_t http_port, bool bounded, double speed) {
    const std::string link = fmt::format("tcp://127.0.0.1:{}", port);
    const std::string web = fmt::format("http://127.0.0.1:{}", http_port);
    fmt::print(stderr,
               "loopwire demo: the gateway owns one simulated RTU line (19200 baud) with an AC20 (unit 1), a ramp/soak "
               "controller (unit 2) and a TC10 (unit 3), process time x{}; below, what its polls read.\n"
               "It shares the line over Modbus TCP on {} - try, from another terminal:\n"
               "  loopwire read  --link {} --device tc10@3 measured_value SP\n"
               "  loopwire write --link {} --device tc10@3 SP=200\n"
               "  loopwire read  --link {} --device ac20@1 St.Pn\n"
               "  loopwire dump  --link {} --device rampsoak@2 --output rampsoak.json\n"
               "  loopwire monitor --link {} --device tc10@3 --device rampsoak@2 --count 5\n"
               "Its dashboard is at {}/ and its HTTP API answers, e.g.:\n"
               "  curl -s {}/api/devices\n"
               "  curl -s {}/api/devices/oven\n"
               "{}\n",
               speed, link, link, link, link, link, link, web, web, web, bounded ? "" : "Ctrl-C stops the demo.");
}

int run_demo(const DemoOptions& options) {
    auto format = monitor_format(options.format, ::isatty(STDOUT_FILENO) == 1);
    if (!format) return report_error(format.error());
    auto duration = demo_duration(options);
    if (!duration) return report_error(duration.error());

    StopSignal stop(*duration);  // before any thread starts, so they inherit the blocked signals
    StreamSampleSink table(stdout, *format);
    SinkOpenedLater sink(table);
    gateway::GatewayOptions gateway_options;
    gateway_options.samples = &sink;
    gateway_options.log = [](const std::string& line) { fmt::print(stderr, "loopwire demo: gateway: {}\n", line); };
    if (options.verbose) gateway_options.trace = stderr_trace();
    auto running = open_demo_gateway(options, gateway_options);
    if (!running) return report_error(running.error());
    const std::uint16_t port = (*running)->modbus_tcp_port();

    Result<void> served;
    std::thread server([&] { served = (*running)->serve(stop.token()); });
    device::MasterOptions client_options;
    client_options.timeout = std::chrono::seconds(2);
    auto client = device::open_link(fmt::format("tcp://127.0.0.1:{}", port), client_options);
    if (client) apply_demo_settings(**client);
    else fmt::print(stderr, "loopwire demo: could not reach the gateway to set the set points: {}\n", client.error().message);
    client = make_error(ErrorKind::link, "closed");  // one client less on the front while it runs
    print_hint(port, (*running)->http_port(), duration->has_value(), options.speed);
    sink.open();
    server.join();
    if (!served) return report_error(served.error());
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
    command->add_option("--http-port", options->http_port, "Loopback port of the dashboard and HTTP API (another if busy; 0 = any)")
        ->check(CLI::Range(0, 65535))->capture_default_str();
    command->add_option("--format", options->format, "table, csv or jsonl (default: table on a terminal, jsonl otherwise)");
    command->add_flag("-v,--verbose", options->verbose, "Print every frame on the demo's line, with timestamps, on stderr");
    command->callback([options, &exit_code] { exit_code = run_demo(*options); });
}

}  // namespace loopwire::app
