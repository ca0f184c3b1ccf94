#include "client/scan.hpp"

#include <algorithm>
#include <optional>

#include <fmt/format.h>

#include "client/device_client.hpp"
#include "client/device_identity.hpp"
#include "common/text_parsing.hpp"
#include "transport/serial_port.hpp"

namespace loopwire::device {
namespace {

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

Result<transport::Parity> parse_parity(const std::string& text) {
    if (text == "none" || text == "n") return transport::Parity::none;
    if (text == "even" || text == "e") return transport::Parity::even;
    if (text == "odd" || text == "o") return transport::Parity::odd;
    return make_error(ErrorKind::usage, fmt::format("parity '{}' is not none, even or odd", text));
}

Result<std::vector<std::uint32_t>> parse_bauds(const std::vector<std::string>& texts, std::uint32_t own) {
    if (texts.empty()) return std::vector<std::uint32_t>{own};
    std::vector<std::uint32_t> bauds;
    for (const auto& text : texts) {
        auto baud = parse_integer(text, 0, 115200, "baud");
        if (!baud) return baud.error();
        if (!transport::is_supported_baud(static_cast<std::uint32_t>(*baud))) {
            return make_error(ErrorKind::usage, fmt::format("baud {} is not a supported rate (600 to 115200)", text));
        }
        bauds.push_back(static_cast<std::uint32_t>(*baud));
    }
    return bauds;
}

Result<std::vector<transport::Parity>> parse_parities(const std::vector<std::string>& texts, transport::Parity own) {
    if (texts.empty()) return std::vector<transport::Parity>{own};
    std::vector<transport::Parity> parities;
    for (const auto& text : texts) {
        auto parity = parse_parity(text);
        if (!parity) return parity.error();
        parities.push_back(*parity);
    }
    return parities;
}

std::string line_text(const transport::LinkUrl& url) {
    if (!url.is_serial()) return url.to_string();
    const char parity = url.serial.parity == transport::Parity::none ? 'N' : url.serial.parity == transport::Parity::even ? 'E' : 'O';
    return fmt::format("{} {}{}{}", url.serial.baud, url.serial.data_bits, parity, url.serial.stop_bits);
}

// Names the unit by its profile and reads the words that profile shows when it identifies one.
void identify(session::Master& master, FoundUnit& found) {
    // A unit that does not answer it in time is scanned on: what it said already proved it there.
    if (auto identity = read_device_identity(master, static_cast<std::uint8_t>(found.unit)); identity && *identity) {
        found.device_identity = identity_json(**identity);
    }
    const auto address = identify_unit(master, found.unit);
    if (!address) return;
    const Profile* profile = address->profile.get();
    found.device = profile->id;
    std::vector<const Parameter*> shown;
    for (const auto& name : profile->identification_report) {
        if (const auto* p = profile->find(name)) shown.push_back(p);
    }
    for (const auto& reading : DeviceClient(master, *address).read(shown).readings) {
        if (reading.value) found.identification[reading.parameter->name] = reading.value->raw;
    }
}

// What one scan keeps while it runs through its settings.
struct ScanRun {
    const std::vector<int>& units;
    const ScanEvents& events;
    const std::stop_token& stop;
    ScanResult result;

    // Tries every unit on one open master.
    void try_units(session::Master& master, const std::string& line) {
        result.found_per_line.emplace_back();
        for (std::size_t i = 0; i < units.size() && !stop.stop_requested(); ++i) {
            const int unit = units[i];
            if (events.trying) events.trying(line, unit, i + 1, units.size(), result.found.size());
            auto reply = master.execute(static_cast<std::uint8_t>(unit), codec::read_request(codec::FunctionCode::read_holding_registers, 0, 1));
            if (!reply && gateway_says_nobody(reply.error())) ++result.gateway_refusals;
            if (!reply && (reply.error().kind != ErrorKind::exception || gateway_says_nobody(reply.error()))) continue;
            FoundUnit unit_found{unit, line, {}, nlohmann::ordered_json::object(), {line}};
            identify(master, unit_found);
            result.found_per_line.back().push_back(unit);
            report(std::move(unit_found), line);
        }
    }

    void report(FoundUnit unit_found, const std::string& line) {
        if (auto* earlier = found_before(result.found, unit_found)) {
            earlier->lines.push_back(line);
            if (events.found) events.found(*earlier);
            return;
        }
        if (events.found) events.found(unit_found);
        result.found.push_back(std::move(unit_found));
    }
};

}  // namespace

Result<UnitScan> UnitScan::plan(const std::string& link, const std::vector<std::string>& bauds, const std::vector<std::string>& parities) {
    auto base = transport::parse_link_url(link);
    if (!base) return base.error();
    if (!base->is_serial() && (!bauds.empty() || !parities.empty())) {
        return make_error(ErrorKind::usage, "--bauds and --parities sweep serial lines; " + link + " is a network link");
    }
    auto baud_list = parse_bauds(bauds, base->serial.baud);
    if (!baud_list) return baud_list.error();
    auto parity_list = parse_parities(parities, base->serial.parity);
    if (!parity_list) return parity_list.error();
    std::vector<transport::LinkUrl> settings;
    for (auto baud : *baud_list) {
        for (auto parity : *parity_list) {
            transport::LinkUrl url = *base;
            url.serial.baud = baud;
            url.serial.parity = parity;
            settings.push_back(url);
        }
    }
    return UnitScan(std::move(settings));
}

std::vector<std::string> UnitScan::settings_text() const {
    std::vector<std::string> texts;
    for (const auto& url : settings_) texts.push_back(line_text(url));
    return texts;
}

Result<ScanResult> UnitScan::run(const std::vector<int>& units, std::chrono::milliseconds timeout, const session::TraceSink& trace,
                                 const ScanEvents& events, const std::stop_token& stop, const MasterOpener& open) const {
    ScanRun run{units, events, stop, {}};
    for (const auto& url : settings_) {
        if (stop.stop_requested()) break;
        auto garbled = std::make_shared<unsigned>(0);
        session::MasterOptions options;
        options.timeout = timeout;
        options.trace = [garbled, trace](const session::TraceEvent& event) {
            if (event.direction == session::TraceDirection::discarded) ++*garbled;
            if (trace) trace(event);
        };
        auto master = open ? open(url, std::move(options)) : session::open_master(url, std::move(options));
        if (!master) return master.error();
        const std::string line = line_text(url);
        run.try_units(**master, line);
        if (events.line_done) events.line_done(line, run.result.found_per_line.back().size(), *garbled);
    }
    run.result.interrupted = stop.stop_requested();
    return std::move(run.result);
}

bool ignores_line_settings(const std::vector<std::vector<int>>& found_per_setting) {
    if (found_per_setting.size() < 2 || found_per_setting.front().empty()) return false;
    return std::all_of(found_per_setting.begin(), found_per_setting.end(),
                       [&](const std::vector<int>& found) { return found == found_per_setting.front(); });
}

}  // namespace loopwire::device
