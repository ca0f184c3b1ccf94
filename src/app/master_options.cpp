#include "app/master_options.hpp"

#include "app/command_line.hpp"

namespace loopwire::app {

void MasterCommandOptions::add_to(CLI::App& command, bool with_device) {
    command.add_option("--link", link, "Link URL: rtu:/dev/ttyUSB0?baud=19200&parity=even, ascii:..., linking:..., tcp://host:502, rtu+tcp://host:4001")
        ->required();
    auto* unit_option = command.add_option("--unit", unit, "Unit (slave) id; 0 broadcasts writes")->check(CLI::Range(0, 255))->capture_default_str();
    if (with_device) {
        command.add_option("--device", device, "DEVICE@UNIT (e.g. tc10@3): name parameters instead of addresses (see `loopwire devices`; --profile FILE.json adds a profile)")
            ->excludes(unit_option);
        command.add_option("--numbering", numbering, "The device's alternative numbering in use (ac20: jbus, when its word 526 says so)");
    }
    command.add_option("--timeout", timeout, "Time to wait for each reply: 500ms, 2s, ...")->capture_default_str();
    command.add_option("--retries", retries, "Extra tries after a timeout or a reply refused as a probable copy")->capture_default_str();
    command.add_flag("-v,--verbose", verbose, "Print every frame sent and received, with timestamps, on stderr");
    command.add_flag("--json", json, "Print the result as JSON");
}

void MasterCommandOptions::add_identify_to(CLI::App& command) {
    command.add_flag("--no-identify", no_identify, "With --device: skip reading the profile's identification words, which "
                                                   "make sure the unit is that device before anything is read or written");
}

Result<std::unique_ptr<device::Master>> MasterCommandOptions::open(device::TraceSink trace) const {
    // The URL is checked before the durations, so its mistakes are the ones reported first.
    if (auto checked = device::check_link_url(link); !checked) return checked.error();
    auto wait = parse_duration(timeout, "--timeout", std::chrono::milliseconds(1));
    if (!wait) return wait.error();
    device::MasterOptions options;
    options.timeout = std::chrono::ceil<std::chrono::milliseconds>(*wait);  // 1.5ms waits 2ms, never less than asked
    options.retries = retries;
    if (verbose) options.trace = trace ? std::move(trace) : stderr_trace();
    return device::open_link(link, std::move(options));
}

}  // namespace loopwire::app
