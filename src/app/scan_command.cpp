// loopwire scan --link URL [--units 1-247] [--bauds 9600,19200] [--parities none,even,odd] [--json]
// Finds the units that answer on a link, optionally sweeping line settings, and identifies each
// by the profiles' identification words. Each unit is printed as it is found; Ctrl-C ends the
// scan with what it found so far (exit 130).
#include <unistd.h>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/scan_report.hpp"
#include "app/stop_signal.hpp"
#include "client/device_client.hpp"
#include "transport/serial_port.hpp"

namespace loopwire::app {
namespace {

struct ScanOptions {
    std::string link;
    std::string units = "1-247";
    std::string bauds;
    std::string parities;
    std::string timeout = "100ms";
    bool json = false;
    bool verbose = false;
};

struct FoundUnit {
    int unit;
    std::string line;  // the first line settings it answered at
    std::string device;
    nlohmann::ordered_json identification = nlohmann::ordered_json::object();
    std::vector<std::string> lines;  // every line setting it answered at, in the order tried
};

// Modbus application protocol V1.1b3, 7: a gateway answers 0Ah (path unavailable) or 0Bh (target
// device failed to respond) for a unit nothing answers behind it: that is nobody, not a device.
bool gateway_says_nobody(const Error& error) {
    return error.kind == ErrorKind::exception && (error.code == 0x0A || error.code == 0x0B);
}

// The unit found earlier as the same device at another line setting, if any: a sweep lists each
// device once, with every setting it answered at.
FoundUnit* found_before(std::vector<FoundUnit>& found, const FoundUnit& unit) {
    for (auto& f : found) {
        if (f.unit == unit.unit && f.device == unit.device) return &f;
    }
    return nullptr;
}

std::vector<std::string> split(const std::string& text) {
    std::vector<std::string> parts;
    std::size_t start = 0;
    while (start <= text.size()) {
        const auto comma = text.find(',', start);
        const std::string part = text.substr(start, comma - start);
        if (!part.empty()) parts.push_back(part);
        if (comma == std::string::npos) break;
        start = comma + 1;
    }
    return parts;
}

// "1-247", "1,3,5-7"; up to 255, where the AC20 and the ramp/soak controller may be set.
Result<std::vector<int>> parse_units(const std::string& text) {
    std::vector<int> units;
    for (const auto& part : split(text)) {
        const auto dash = part.find('-');
        auto first = parse_integer(part.substr(0, dash), 1, 255, "unit");
        if (!first) return first.error();
        auto last = dash == std::string::npos ? first : parse_integer(part.substr(dash + 1), *first, 255, "last unit of '" + part + "'");
        if (!last) return last.error();
        for (long long unit = *first; unit <= *last; ++unit) units.push_back(static_cast<int>(unit));
    }
    if (units.empty()) return make_error(ErrorKind::usage, "--units names no unit (write e.g. 1-247 or 1,3,7-9)");
    return units;
}

Result<transport::Parity> parse_parity(const std::string& text) {
    if (text == "none" || text == "n") return transport::Parity::none;
    if (text == "even" || text == "e") return transport::Parity::even;
    if (text == "odd" || text == "o") return transport::Parity::odd;
    return make_error(ErrorKind::usage, fmt::format("parity '{}' is not none, even or odd", text));
}

// Every line setting to try: the URL's own, or the sweep the options ask for.
Result<std::vector<transport::LinkUrl>> line_settings(const ScanOptions& options) {
    auto base = transport::parse_link_url(options.link);
    if (!base) return base.error();
    if (!base->is_serial() && (!options.bauds.empty() || !options.parities.empty())) {
        return make_error(ErrorKind::usage, "--bauds and --parities sweep serial lines; " + options.link + " is a network link");
    }
    std::vector<std::uint32_t> bauds{base->serial.baud};
    if (!options.bauds.empty()) bauds.clear();
    for (const auto& text : split(options.bauds)) {
        auto baud = parse_integer(text, 0, 115200, "baud");
        if (!baud) return baud.error();
        if (!transport::is_supported_baud(static_cast<std::uint32_t>(*baud))) {
            return make_error(ErrorKind::usage, fmt::format("baud {} is not a supported rate (600 to 115200)", text));
        }
        bauds.push_back(static_cast<std::uint32_t>(*baud));
    }
    std::vector<transport::Parity> parities{base->serial.parity};
    if (!options.parities.empty()) parities.clear();
    for (const auto& text : split(options.parities)) {
        auto parity = parse_parity(text);
        if (!parity) return parity.error();
        parities.push_back(*parity);
    }
    std::vector<transport::LinkUrl> settings;
    for (auto baud : bauds) {
        for (auto parity : parities) {
            transport::LinkUrl url = *base;
            url.serial.baud = baud;
            url.serial.parity = parity;
            settings.push_back(url);
        }
    }
    return settings;
}

std::string line_text(const transport::LinkUrl& url) {
    if (!url.is_serial()) return url.to_string();
    const char parity = url.serial.parity == transport::Parity::none ? 'N' : url.serial.parity == transport::Parity::even ? 'E' : 'O';
    return fmt::format("{} {}{}{}", url.serial.baud, url.serial.data_bits, parity, url.serial.stop_bits);
}

// Reads each profile's identification words; the first profile whose checks all hold names it.
void identify(session::Master& master, FoundUnit& found) {
    for (const auto& id : device::builtin_profile_ids()) {
        auto address = device::parse_device_address(id + "@" + std::to_string(found.unit));
        if (!address) continue;
        const auto& profile = *address->profile;
        std::vector<const device::Parameter*> checks;
        for (const auto& check : profile.identification) {
            if (const auto* p = profile.find(check.parameter)) checks.push_back(p);
        }
        if (checks.empty()) continue;
        device::DeviceClient client(master, *address);
        const auto report = client.read(checks);
        bool all_hold = !report.first_error;
        for (const auto& check : profile.identification) {
            auto raw = report.raw.find(check.parameter);
            all_hold = all_hold && raw != report.raw.end() && static_cast<std::int16_t>(raw->second) == static_cast<std::int16_t>(check.equals);
        }
        if (!all_hold) continue;
        found.device = id;
        std::vector<const device::Parameter*> shown;
        for (const auto& name : profile.identification_report) {
            if (const auto* p = profile.find(name)) shown.push_back(p);
        }
        for (const auto& reading : client.read(shown).readings) {
            if (reading.value) found.identification[reading.parameter->name] = reading.value->raw;
        }
        return;
    }
}

std::string units_text(const std::vector<int>& units) { return fmt::format("{}", fmt::join(units, ", ")); }

// Prints a unit on stdout as soon as it is found, so a long scan shows its results as it goes
// and a scan stopped early has already shown them.
void print_found(const FoundUnit& f, bool json) {
    if (json) return;  // one JSON document at the end
    if (f.lines.size() > 1) {
        fmt::print("unit {:>3}  {:<10} also at {}\n", f.unit, f.device.empty() ? "(unknown Modbus device)" : f.device, f.lines.back());
        std::fflush(stdout);
        return;
    }
    fmt::print("unit {:>3}  {:<10} {:<12} {}\n", f.unit, f.device.empty() ? "(unknown Modbus device)" : f.device, f.line,
               f.identification.empty() ? "" : f.identification.dump());
    std::fflush(stdout);
}

std::string settings_text(const std::vector<transport::LinkUrl>& settings) {
    std::vector<std::string> texts;
    for (const auto& url : settings) texts.push_back(line_text(url));
    return fmt::format("{}", fmt::join(texts, ", "));
}

void print_summary(const std::vector<FoundUnit>& found, bool json, bool interrupted) {
    if (json) {
        nlohmann::ordered_json list = nlohmann::ordered_json::array();
        for (const auto& f : found) {
            list.push_back({{"unit", f.unit}, {"device", f.device.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(f.device)},
                            {"identification", f.identification}, {"line", f.line}, {"lines", f.lines}});
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

int run_scan(const ScanOptions& options) {
    auto units = parse_units(options.units);
    if (!units) return report_error(units.error());
    auto settings = line_settings(options);
    if (!settings) return report_error(settings.error());
    auto wait = parse_duration(options.timeout, "--timeout", std::chrono::milliseconds(1));
    if (!wait) return report_error(wait.error());

    StopSignal stop;  // before any link's threads start, so only its thread takes Ctrl-C
    std::vector<FoundUnit> found;
    std::vector<std::vector<int>> found_per_line;  // for the check that the line ignores its settings
    std::size_t gateway_refusals = 0;
    ScanProgress progress(::isatty(STDERR_FILENO) == 1);
    for (const auto& url : *settings) {
        if (stop.token().stop_requested()) break;
        auto garbled = std::make_shared<unsigned>(0);
        session::MasterOptions master_options;
        master_options.timeout = std::chrono::ceil<std::chrono::milliseconds>(*wait);
        auto verbose = options.verbose ? stderr_trace() : session::TraceSink{};
        master_options.trace = [garbled, verbose](const session::TraceEvent& event) {
            if (event.direction == session::TraceDirection::discarded) ++*garbled;
            if (verbose) verbose(event);
        };
        auto master = session::open_master(url, master_options);
        if (!master) return report_error(master.error());
        found_per_line.emplace_back();
        for (std::size_t i = 0; i < units->size() && !stop.token().stop_requested(); ++i) {
            const int unit = (*units)[i];
            progress.show(line_text(url), unit, i + 1, units->size(), found.size());
            // Any answer proves a unit is there, an exception included (the TC10 refuses
            // address 0 with exception 2); only silence means nobody.
            auto reply = (*master)->execute(static_cast<std::uint8_t>(unit), codec::read_request(codec::FunctionCode::read_holding_registers, 0, 1));
            if (!reply && gateway_says_nobody(reply.error())) ++gateway_refusals;
            if (!reply && (reply.error().kind != ErrorKind::exception || gateway_says_nobody(reply.error()))) continue;
            FoundUnit unit_found{unit, line_text(url), {}, nlohmann::ordered_json::object(), {line_text(url)}};
            identify(**master, unit_found);
            progress.clear();
            found_per_line.back().push_back(unit);
            if (auto* earlier = found_before(found, unit_found)) {
                earlier->lines.push_back(line_text(url));
                print_found(*earlier, options.json);
                continue;
            }
            print_found(unit_found, options.json);
            found.push_back(std::move(unit_found));
        }
        progress.clear();
        if (found_per_line.back().empty() && *garbled > 0) {
            fmt::print(stderr, "loopwire: {} garbled replies at {} and no unit answered cleanly: the usual cause of CRC errors is a wrong baud rate or parity; try --bauds and --parities\n",
                       *garbled, line_text(url));
        }
    }
    const bool interrupted = stop.token().stop_requested();
    if (!interrupted && ignores_line_settings(found_per_line)) {
        fmt::print(stderr,
                   "loopwire: warning: every line setting found the same units ({}) at {}: the line probably ignores line "
                   "settings (a pseudo-terminal, or a converter that sets its own speed and parity), so these results do not "
                   "tell which setting the devices use\n",
                   units_text(found_per_line.front()), settings_text(*settings));
    }
    if (gateway_refusals > 0 && !options.json) {
        fmt::print(stderr, "loopwire: {} unit(s) were answered by a gateway with exception 0Ah or 0Bh (nothing answers behind it "
                           "at that unit); they are not counted\n", gateway_refusals);
    }
    print_summary(found, options.json, interrupted);
    return interrupted ? exit_interrupted : exit_ok;
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
    command->add_flag("--json", options->json, "Print the result as JSON (at the end; without it each unit is printed as it is found)");
    command->add_flag("-v,--verbose", options->verbose, "Print every frame, with timestamps, on stderr");
    command->footer(exit_code_help);
    command->callback([options, &exit_code] { exit_code = run_scan(*options); });
}

}  // namespace loopwire::app
