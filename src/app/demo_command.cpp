// loopwire demo: the embedded default behind the README's first command. For now: a simulated
// slave on a pseudo-terminal, and a master that writes and reads it through that terminal, the
// way an outside program would.
#include <cstdlib>
#include <filesystem>
#include <thread>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/stop_signal.hpp"
#include "session/master.hpp"
#include "session/register_bank.hpp"
#include "session/slave.hpp"
#include "transport/pseudo_terminal.hpp"
#include "transport/serial_port.hpp"

namespace loopwire::app {
namespace {

struct DemoOptions {
    std::string duration = "0s";
    bool verbose = false;
};

std::string make_demo_dir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "loopwire-demo-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) return {};
    return pattern;
}

Result<void> exercise(session::Master& master) {
    const std::vector<std::uint16_t> values{1250, 0xFF9C, 0x8000, 700};
    fmt::print("write holding registers 100..103 = 1250, -100, 8000h, 700 (function 16)\n");
    if (auto written = master.execute(1, codec::write_multiple_registers(100, values)); !written) return written.error();
    auto read = master.execute(1, codec::read_request(codec::FunctionCode::read_holding_registers, 100, 4));
    if (!read) return read.error();
    fmt::print("read  holding registers 100..103 (function 3):\n");
    for (std::size_t i = 0; i < read->values.size(); ++i) {
        fmt::print("  {:5}  {:5}  0x{:04X}  {:6}\n", 100 + i, read->values[i], read->values[i], static_cast<std::int16_t>(read->values[i]));
    }
    if (read->values != values) return make_error(ErrorKind::mismatch, "the values read back differ from those written");
    return {};
}

int run_demo(const DemoOptions& options) {
    auto limit = parse_duration(options.duration);
    if (!limit) return report_error(limit.error());
    const std::string dir = make_demo_dir();
    if (dir.empty()) return report_error(make_error(ErrorKind::link, "cannot create a temporary directory for the demo's pseudo-terminal"));
    const std::string pty_path = dir + "/ttyLW0";
    auto url = transport::parse_link_url("rtu:" + pty_path + "?baud=19200&parity=even");
    if (!url) return report_error(url.error());

    auto slave_side = transport::create_pseudo_terminal(pty_path, url->serial);
    if (!slave_side) return report_error(slave_side.error());
    StopSignal stop(*limit);
    session::Slave slave(*url, {{1, std::make_shared<session::RegisterBank>()}});
    std::jthread simulator([&](std::stop_token) { (void)slave.serve_stream(**slave_side, stop.token()); });

    fmt::print("loopwire demo: a simulated unit 1 serves Modbus RTU at 19200 8E1 on the pseudo-terminal {}\n\n", pty_path);
    session::MasterOptions master_options;
    if (options.verbose) master_options.trace = stderr_trace();
    auto master = session::open_master(*url, master_options);
    int status = exit_ok;
    if (!master) {
        status = report_error(master.error());
    } else if (auto done = exercise(**master); !done) {
        status = report_error(done.error());
    }
    master = make_error(ErrorKind::link, "closed");  // release the port for other programs
    if (status == exit_ok) {
        fmt::print("\nTry it yourself while the demo runs (loopwire demo --duration 60s):\n"
                   "  loopwire read  --link 'rtu:{0}?baud=19200&parity=even' --unit 1 holding 100 4\n"
                   "  loopwire write --link 'rtu:{0}?baud=19200&parity=even' --unit 1 holding 100 42\n"
                   "  mbpoll -m rtu -b 19200 -P even -a 1 -0 -r 100 -c 4 -1 {0}\n",
                   pty_path);
        if (limit->count() > 0) fmt::print("\nserving for {} (Ctrl-C stops)\n", options.duration);
        std::fflush(stdout);
    }
    if (status != exit_ok || limit->count() == 0) stop.request_stop();
    simulator.join();
    slave_side = make_error(ErrorKind::link, "closed");  // removes the link before the directory
    std::filesystem::remove_all(dir);
    return status;
}

}  // namespace

void add_demo_command(CLI::App& app, int& exit_code) {
    auto options = std::make_shared<DemoOptions>();
    auto* command = app.add_subcommand("demo", "Run a simulated device on a pseudo-terminal and talk to it");
    command->add_option("--duration", options->duration, "Keep the simulator serving this long after the demo (e.g. 60s)")->capture_default_str();
    command->add_flag("-v,--verbose", options->verbose, "Print every frame, with timestamps, on stderr");
    command->callback([options, &exit_code] { exit_code = run_demo(*options); });
}

}  // namespace loopwire::app
