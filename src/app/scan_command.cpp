// loopwire scan --link URL [--units 1-247] [--bauds 9600,19200] [--parities none,even,odd] [--json]
//               [--emit-config FILE]
// Finds the units that answer on a link, optionally sweeping line settings, and identifies each
// by the profiles' identification words and by Read Device Identification where it has it;
// --emit-config writes a gateway configuration of what it found. Each unit is printed as it is found; Ctrl-C ends the
// scan with what it found so far (exit 130).
#include <unistd.h>

#include <algorithm>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/scan_report.hpp"
#include "app/stop_signal.hpp"
#include "client/scan.hpp"
#include "client/scan_config.hpp"
#include "common/atomic_file.hpp"

namespace loopwire::app {
namespace {

struct ScanOptions {
    std::string link;
    std::string units = "1-247";
    std::string bauds;
    std::string parities;
    std::string timeout = "100ms";
    std::string emit_config;  // FILE: a gateway configuration of what was found
    bool json = false;
    bool verbose = false;
};

// A comma-separated list of `option` ("" when the option is not given); an empty element ("1,,3",
// a trailing comma) is a value left out by mistake, refused rather than skipped in silence.
Result<std::vector<std::string>> split(const std::string& text, std::string_view option, std::string_view example) {
    std::vector<std::string> parts;
    if (text.empty()) return parts;
    std::size_t start = 0;
    while (start <= text.size()) {
        const auto comma = text.find(',', start);
        std::string part = text.substr(start, comma - start);
        if (part.empty()) {
            return make_error(ErrorKind::usage, fmt::format("{} '{}' has an empty element between commas (write e.g. {})", option, text, example));
        }
        parts.push_back(std::move(part));
        if (comma == std::string::npos) break;
        start = comma + 1;
    }
    return parts;
}

// "1-247", "1,3,5-7"; up to 255, where the AC20 and the ramp/soak controller may be set.
Result<std::vector<int>> parse_units(const std::string& text) {
    std::vector<int> units;
    auto parts = split(text, "--units", "1,3,7-9");
    if (!parts) return parts.error();
    for (const auto& part : *parts) {
        const auto dash = part.find('-');
        auto first = parse_integer(part.substr(0, dash), 1, 255, "unit");
        if (!first) return first.error();
        auto last = dash == std::string::npos ? first : parse_integer(part.substr(dash + 1), *first, 255, "last unit of '" + part + "'");
        if (!last) return last.error();
        // Each unit once, in the order first named: "3,3" or "1-5,4" would probe a unit twice and list
        // it answering twice.
        for (long long unit = *first; unit <= *last; ++unit) {
            if (std::find(units.begin(), units.end(), unit) == units.end()) units.push_back(static_cast<int>(unit));
        }
    }
    if (units.empty()) return make_error(ErrorKind::usage, "--units names no unit (write e.g. 1-247 or 1,3,7-9)");
    return units;
}

std::string units_text(const std::vector<int>& units) { return fmt::format("{}", fmt::join(units, ", ")); }

// Prints a unit on stdout as soon as it is found, so a long scan shows its results as it goes
// and a scan stopped early has already shown them.
void print_found(const device::FoundUnit& f, bool json) {
    if (json) return;  // one JSON document at the end
    if (f.lines.size() > 1) {
        fmt::print("unit {:>3}  {:<10} also at {}\n", f.unit, f.device.empty() ? "(unknown Modbus device)" : f.device, f.lines.back());
        std::fflush(stdout);
        return;
    }
    fmt::print("unit {:>3}  {:<10} {:<12} {}{}\n", f.unit, f.device.empty() ? "(unknown Modbus device)" : f.device, f.line,
               f.identification.empty() ? "" : f.identification.dump(),
               f.device_identity.is_null() ? "" : (f.identification.empty() ? "" : " ") + f.device_identity.dump());
    std::fflush(stdout);
}

void print_summary(const std::vector<device::FoundUnit>& found, bool json, bool interrupted) {
    if (json) {
        nlohmann::ordered_json list = nlohmann::ordered_json::array();
        for (const auto& f : found) {
            list.push_back({{"unit", f.unit}, {"device", f.device.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(f.device)},
                            {"identification", f.identification}, {"device_identity", f.device_identity},
                            {"line", f.line}, {"lines", f.lines}});
        }
        nlohmann::ordered_json out{{"units", list}};
        if (interrupted) out["interrupted"] = true;
        fmt::print("{}\n", out.dump());
    } else {
        fmt::print("{} unit(s) answered{}\n", found.size(), interrupted ? " before the scan was interrupted (not every unit was tried)" : "");
        for (const auto& f : found) {
            if (f.lines.size() > 1) fmt::print("unit {} answered at {}\n", f.unit, fmt::join(f.lines, ", "));
        }
    }
    std::fflush(stdout);
}

// Prints as the scan goes: progress on a terminal, each unit as it is found, and a line's
// garbled replies when nobody answered there cleanly.
device::ScanEvents scan_printer(ScanProgress& progress, bool json) {
    device::ScanEvents events;
    events.trying = [&progress](const std::string& line, int unit, std::size_t index, std::size_t total, std::size_t found) {
        progress.show(line, unit, index, total, found);
    };
    events.found = [&progress, json](const device::FoundUnit& unit) {
        progress.clear();
        print_found(unit, json);
    };
    events.line_done = [&progress](const std::string& line, std::size_t answered, unsigned garbled) {
        progress.clear();
        if (answered == 0 && garbled > 0) {
            fmt::print(stderr, "loopwire: {} garbled replies at {} and no unit answered cleanly: the usual cause of CRC errors is a wrong baud rate or parity; try --bauds and --parities\n",
                       garbled, line);
        }
    };
    return events;
}

void print_warnings(const device::ScanResult& result, const device::UnitScan& scan, bool json) {
    if (!result.interrupted && device::ignores_line_settings(result.found_per_line)) {
        fmt::print(stderr,
                   "loopwire: warning: every line setting found the same units ({}) at {}: the line probably ignores line "
                   "settings (a pseudo-terminal, or a converter that sets its own speed and parity), so these results do not "
                   "tell which setting the devices use\n",
                   units_text(result.found_per_line.front()), fmt::join(scan.settings_text(), ", "));
    }
    if (result.gateway_refusals > 0 && !json) {
        fmt::print(stderr, "loopwire: {} unit(s) were answered by a gateway with exception 0Ah or 0Bh (nothing answers behind it "
                           "at that unit); they are not counted\n", result.gateway_refusals);
    }
}

// A configuration needs a device to poll: without one identified, nothing is written.
Result<void> emit_config(const std::string& path, const device::UnitScan& scan, const std::vector<device::FoundUnit>& found) {
    const bool identified = std::any_of(found.begin(), found.end(), [](const device::FoundUnit& f) { return !f.device.empty(); });
    if (!identified) {
        return make_error(ErrorKind::usage, fmt::format("--emit-config {}: no unit answered as a device loopwire has a profile "
                                                        "for, so there is no device to configure; nothing was written", path));
    }
    if (auto written = write_file_atomically(path, device::scan_configuration(scan, found)); !written) {
        return written.error();
    }
    fmt::print(stderr, "loopwire: wrote {}; check it with: loopwire gateway --config {} --check\n", path, path);
    return {};
}

int run_scan(const ScanOptions& options) {
    auto units = parse_units(options.units);
    if (!units) return report_error(units.error());
    auto bauds = split(options.bauds, "--bauds", "9600,19200");
    if (!bauds) return report_error(bauds.error());
    auto parities = split(options.parities, "--parities", "none,even");
    if (!parities) return report_error(parities.error());
    auto scan = device::UnitScan::plan(options.link, *bauds, *parities);
    if (!scan) return report_error(scan.error());
    auto wait = parse_duration(options.timeout, "--timeout", std::chrono::milliseconds(1));
    if (!wait) return report_error(wait.error());
    if (!options.emit_config.empty()) {
        // Said before a long scan, not after it.
        if (auto writable = check_writable_atomically(options.emit_config); !writable) return report_error(writable.error());
    }

    StopSignal stop;  // before any link's threads start, so only its thread takes Ctrl-C
    ScanProgress progress(::isatty(STDERR_FILENO) == 1);
    auto result = scan->run(*units, std::chrono::ceil<std::chrono::milliseconds>(*wait), options.verbose ? stderr_trace() : device::TraceSink{},
                            scan_printer(progress, options.json), stop.token());
    if (!result) return report_error(result.error());
    print_warnings(*result, *scan, options.json);
    print_summary(result->found, options.json, result->interrupted);
    if (!options.emit_config.empty()) {
        if (auto written = emit_config(options.emit_config, *scan, result->found); !written) return report_error(written.error());
    }
    return result->interrupted ? exit_interrupted : exit_ok;
}

}  // namespace

void add_scan_command(CLI::App& app, int& exit_code) {
    auto options = std::make_shared<ScanOptions>();
    auto* command = app.add_subcommand("scan", "Find the units that answer on a link and identify them (Ctrl-C keeps what was found)");
    command->add_option("--link", options->link, "Link URL to scan")->required();
    command->add_option("--units", options->units, "Units to try: 1-247, or a list like 1,3,7-9 (up to 255)")->capture_default_str();
    command->add_option("--bauds", options->bauds, "Serial: baud rates to sweep, e.g. 9600,19200,38400");
    command->add_option("--parities", options->parities, "Serial: parities to sweep, e.g. none,even,odd");
    command->add_option("--timeout", options->timeout, "Time to wait for each unit")->capture_default_str();
    command->add_option("--emit-config", options->emit_config,
                        "Write a gateway configuration (TOML) of the units found to FILE: the line as scanned, a device per "
                        "unit identified, comments for the rest");
    command->add_flag("--json", options->json, "Print the result as JSON (at the end; without it each unit is printed as it is found)");
    command->add_flag("-v,--verbose", options->verbose, "Print every frame, with timestamps, on stderr");
    command->footer(exit_code_help);
    command->callback([options, &exit_code] { exit_code = run_scan(*options); });
}

}  // namespace loopwire::app
