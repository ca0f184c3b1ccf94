// loopwire simulate --link URL [--device DEVICE@UNIT ...] [--unit N ...] [--pty PATH] [--state FILE]
//                   [--seed N] [--speed X] [--fault DEVICE@UNIT:FAULT ...] [--duration S] [-v]
// --device serves a simulated controller: its behaviour model (devices/<id>/) over its
// profile; --unit a plain register bank (all four tables, 65536 entries, zero, writable).
#include <condition_variable>
#include <mutex>
#include <optional>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/stop_signal.hpp"
#include "devices/simulated_units.hpp"
#include "simulation/simulator_server.hpp"
#include "simulation/state_file.hpp"

namespace loopwire::app {
namespace {

struct SimulateOptions {
    std::string link;
    std::vector<int> units;
    std::vector<std::string> devices;
    std::string pty;
    std::string duration;
    std::string state;
    std::uint64_t seed = 1;
    double speed = 1.0;
    std::vector<std::string> faults;
    bool verbose = false;
};

// Saves the state file while the simulator runs, a quarter second after a change at most, so
// a crash or kill loses no more than that. A save that fails does not stop the simulator (the
// masters on the line depend on it, and the cause — a full disk, a removed folder — is often
// passing): it is reported on stderr, retried every few seconds, and its recovery reported
// too. On the way out a last save is tried; finish() fails when a change is still unsaved,
// so the run never ends quietly with an acknowledged write lost.
class StateSaver {
public:
    explicit StateSaver(device::SimulatorStateFile& file) : file_(file), thread_([this](std::stop_token own) { run(own); }) {}
    ~StateSaver() { thread_.request_stop(); }
    Result<void> finish() {
        thread_.request_stop();
        if (thread_.joinable()) thread_.join();
        if (auto saved = file_.save_if_changed(); !saved) {
            return make_error(saved.error().kind, fmt::format("values written to the simulated devices (acknowledged to the "
                                                              "master) are NOT saved in the state file: {}",
                                                              saved.error().message));
        }
        return {};
    }

private:
    static constexpr auto poll_interval = std::chrono::milliseconds(250);
    static constexpr auto retry_interval = std::chrono::seconds(2);

    void run(std::stop_token own) {
        std::mutex mutex;
        std::condition_variable_any wake;
        std::unique_lock lock(mutex);
        std::string reported;  // the failure last reported, so a lasting one is said once
        auto next_try = std::chrono::steady_clock::now();
        while (!own.stop_requested()) {
            wake.wait_for(lock, own, poll_interval, [] { return false; });
            if (own.stop_requested() || std::chrono::steady_clock::now() < next_try) continue;
            if (auto saved = file_.save_if_changed(); !saved) {
                if (saved.error().message != reported) {
                    fmt::print(stderr, "loopwire: error: saving the state failed: {}; still serving, retrying every {} s\n",
                               saved.error().message, retry_interval.count());
                    reported = saved.error().message;
                }
                next_try = std::chrono::steady_clock::now() + retry_interval;
            } else if (!reported.empty()) {
                fmt::print(stderr, "loopwire: the state is saved again\n");
                reported.clear();
            }
        }
    }

    device::SimulatorStateFile& file_;
    std::jthread thread_;
};

void announce(const device::models::SimulatedUnits& served) {
    for (const std::string& warning : served.warnings) fmt::print(stderr, "loopwire: warning: {}\n", warning);
    for (const std::string& line : served.descriptions) fmt::print(stderr, "loopwire: unit {}\n", line);
}

std::string unit_list(const device::SimulatedUnitMap& units) {
    std::vector<int> ids;
    for (const auto& [unit, handler] : units) ids.push_back(unit);
    return fmt::format("{}", fmt::join(ids, ", "));
}

int run_simulate(SimulateOptions options, const ProfileOptions& profiles) {
    auto where = device::simulator_link(options.link, options.pty);
    if (!where) return report_error(where.error());
    std::optional<std::chrono::microseconds> limit;
    if (!options.duration.empty()) {
        auto parsed = parse_duration(options.duration, "--duration");
        if (!parsed) return report_error(parsed.error());
        limit = *parsed;
    }
    device::SimulationEnvironment environment;
    environment.speed = options.speed;
    environment.seed = options.seed;
    auto registry = profiles.load();
    if (!registry) return report_error(registry.error());
    auto served_units = device::models::build_simulated_units(*registry, options.units, options.devices, where->url, environment);
    if (!served_units) return report_error(served_units.error());
    for (const std::string& fault : options.faults) {
        if (auto applied = device::models::apply_fault_option(*served_units, fault); !applied) return report_error(applied.error());
    }
    std::optional<device::SimulatorStateFile> state;
    if (!options.state.empty()) {
        auto opened = device::SimulatorStateFile::open(options.state, served_units->devices);
        if (!opened) return report_error(opened.error());
        state.emplace(std::move(*opened));
        served_units->warnings.insert(served_units->warnings.end(), state->warnings().begin(), state->warnings().end());
    }
    announce(*served_units);
    const std::string units_text = unit_list(served_units->units);
    StopSignal stop(limit);
    device::SimulatorOptions slave_options;
    if (options.verbose) slave_options.trace = stderr_trace();
    auto server = device::SimulatorServer::open(*where, std::move(served_units->units), std::move(slave_options));
    if (!server) return report_error(server.error());
    std::optional<StateSaver> saver;
    if (state) saver.emplace(*state);
    fmt::print(stderr, "loopwire: simulating unit(s) {} on {} ({}); Ctrl-C to stop\n", units_text, where->url.to_string(),
               (*server)->opened());
    const Result<void> served = (*server)->serve(stop.token());
    if (saver) {
        if (auto saved = saver->finish(); !saved) return report_error(saved.error());
    }
    if (!served) return report_error(served.error());
    fmt::print(stderr, "loopwire: stopped after serving {} request(s)\n", (*server)->requests_served());
    return exit_ok;
}

}  // namespace

void add_simulate_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<SimulateOptions>();
    auto* command = app.add_subcommand("simulate", "Serve simulated devices and plain register banks on a link");
    command->add_option("--link", options->link, "Link URL to serve on: rtu:/dev/ttyUSB0?baud=19200, tcp://127.0.0.1:1502, rtu+tcp://0.0.0.0:4001");
    command->add_option("--device", options->devices, "Simulated device to serve, DEVICE@UNIT (ac20@1, tc10@3, rampsoak@5; repeat for several)");
    command->add_option("--unit", options->units, "Unit id to serve as a plain register bank (repeat for several; default 1 when no --device)")->check(CLI::Range(1, 247));
    command->add_option("--pty", options->pty, "Create a pseudo-terminal with a link at PATH and serve there (open PATH like a serial port)");
    command->add_option("--state", options->state, "Keep what the devices hold in non-volatile memory in FILE across restarts (RAM-only values are lost, as on the real device)");
    command->add_option("--seed", options->seed, "Seed of the simulated measurement noise, for runs that repeat exactly (default 1)")
        ->check([](const std::string& text) {
            // CLI11 would take "-1" for an unsigned number, wrapped round.
            return text.find('-') == std::string::npos ? std::string() : "a seed is a whole number from 0 up, e.g. --seed 7";
        });
    command->add_option("--speed", options->speed, "Run the process (plant, program timers) X times faster than real time; protocol timing stays real (default 1)")
        ->check(CLI::Range(0.001, 100000.0));
    command->add_option("--fault", options->faults, "Inject a fault at start, DEVICE@UNIT:FAULT (e.g. tc10@3:open-input; repeat for several)");
    command->add_option("--duration", options->duration, "Stop by itself after this long (e.g. 30s)");
    command->add_flag("-v,--verbose", options->verbose, "Print every frame received and sent, with timestamps, on stderr");
    command->footer(exit_code_help);
    command->callback([options, &exit_code, &profiles] { exit_code = run_simulate(*options, profiles); });
}

}  // namespace loopwire::app
