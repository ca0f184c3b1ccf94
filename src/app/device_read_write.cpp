#include "app/device_read_write.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/json_errors.hpp"
#include "app/exit_codes.hpp"
#include "profile/value_format.hpp"
#include "client/device_client.hpp"
#include "client/resolved_value.hpp"

namespace loopwire::app {
namespace {

struct Connected {
    device::DeviceAddress device;
    std::unique_ptr<device::Master> master;
};

Result<Connected> connect(const device::ProfileRegistry& profiles, const MasterCommandOptions& options) {
    auto device = device::parse_device_address(profiles, options.device, options.numbering);
    if (!device) return device.error();
    auto master = options.open();
    if (!master) return master.error();
    return Connected{std::move(*device), std::move(*master)};
}

// What failed in a read, if anything: the first failed request, or else a value the profile
// cannot decode (a decimals or unit word out of its range: the device is probably not the one
// named), which must not pass as a success.
std::optional<Error> read_failure(const device::ReadReport& report) {
    if (report.first_error) return report.first_error;
    std::size_t failed = 0;
    const device::ParameterReading* first = nullptr;
    for (const auto& reading : report.readings) {
        if (reading.value) continue;
        ++failed;
        if (first == nullptr) first = &reading;
    }
    if (first == nullptr) return std::nullopt;
    return make_error(ErrorKind::mismatch, fmt::format("{} of {} value(s) could not be decoded (first: {}: {})", failed,
                                                       report.readings.size(), first->parameter->name, first->error));
}

void print_readings(const MasterCommandOptions& options, const device::DeviceAddress& device, const device::ReadReport& report,
                    const std::optional<Error>& failure) {
    if (options.json) {
        nlohmann::ordered_json values = nlohmann::ordered_json::object();
        for (const auto& reading : report.readings) {
            const auto* value = reading.value ? &*reading.value : nullptr;
            values[reading.parameter->name] = device::resolved_json(*reading.parameter, value, device::resolve_reading(reading, report.raw));
        }
        nlohmann::ordered_json out{{"unit", device.unit}, {"device", device.profile->id}, {"values", values}};
        if (failure) {  // the one JSON document says it failed, as error_json would
            out["error"] = error_json(*failure)["error"];
            out["kind"] = error_json(*failure)["kind"];
        }
        fmt::print("{}\n", out.dump());
        return;
    }
    for (const auto& reading : report.readings) {
        const auto& p = *reading.parameter;
        const auto resolved = device::resolve_reading(reading, report.raw);
        if (!resolved.raw) {
            fmt::print("{:<34} {:<8} error: {}\n", p.name, p.mnemonic, resolved.error);
            continue;
        }
        fmt::print("{:<34} {:<8} {:>12} {:<6} {}{}\n", p.name, p.mnemonic, resolved.text, resolved.unit,
                   resolved.status == "ok" ? "" : resolved.status + " ", fmt::format("(raw {})", *resolved.raw));
    }
}

}  // namespace

int run_device_read(const device::ProfileRegistry& profiles, const MasterCommandOptions& options, const std::vector<std::string>& names) {
    if (names.empty()) return report_error(make_error(ErrorKind::usage, "name the parameters to read (names, mnemonics, a group, or all); `loopwire describe DEVICE` lists them"));
    auto device = device::parse_device_address(profiles, options.device, options.numbering);
    if (!device) return report_error(device.error());
    auto parameters = device::resolve_parameters(*device->profile, names);
    if (!parameters) return report_error(parameters.error());
    auto connected = connect(profiles, options);
    if (!connected) return report_error(connected.error());
    device::DeviceClient client(*connected->master, connected->device);
    if (!options.no_identify) {
        auto same = client.confirm_identity();
        if (!same) return report_error(same.error());
    }
    const auto report = client.read_with_limits(*parameters);
    const auto failure = read_failure(report);
    print_readings(options, connected->device, report, failure);
    if (failure) {
        if (options.json) return exit_code_for(*failure);  // the document printed says it
        return report_error(*failure);
    }
    return exit_ok;
}

int run_device_write(const device::ProfileRegistry& profiles, const MasterCommandOptions& options, const std::vector<std::string>& assignments) {
    if (assignments.empty()) return report_error(make_error(ErrorKind::usage, "give NAME=VALUE pairs to write"));
    auto device = device::parse_device_address(profiles, options.device, options.numbering);
    if (!device) return report_error(device.error());
    std::vector<std::pair<const device::Parameter*, std::string>> resolved;
    for (const auto& assignment : assignments) {
        const auto equals = assignment.find('=');
        if (equals == std::string::npos || equals == 0) {
            return report_error(make_error(ErrorKind::usage, fmt::format("'{}' is not NAME=VALUE", assignment)));
        }
        auto found = device::resolve_parameters(*device->profile, {assignment.substr(0, equals)});
        if (!found) return report_error(found.error());
        if (found->size() != 1) {
            return report_error(make_error(ErrorKind::usage, fmt::format("'{}' names a group: write parameters one by one", assignment.substr(0, equals))));
        }
        const device::Parameter* parameter = found->front();
        // Checked before the link is opened: a read-only name is a mistake whatever the device says.
        if (!parameter->writable) {
            return report_error(make_error(ErrorKind::usage, fmt::format("{} ({}) is read-only", parameter->name, parameter->mnemonic)));
        }
        resolved.emplace_back(parameter, assignment.substr(equals + 1));
    }
    auto connected = connect(profiles, options);
    if (!connected) return report_error(connected.error());
    device::DeviceClient client(*connected->master, connected->device);
    if (!options.no_identify) {  // before anything is written to a device that may be another
        auto same = client.confirm_identity();
        if (!same) return report_error(same.error());
    }
    auto written = client.write(resolved);
    if (!written) return report_error(written.error());
    // The unit as a read would show it (unit_of): a unit that follows a configuration word
    // (TC10 unit, AC20 PV.SL/tP.In, ramp/soak UNIT) comes from that word, which write() read
    // with the decimals and bounds before writing, or took from this command's own assignments.
    const auto unit = [&](const device::Parameter& p) { return device::unit_of(p, written->known); };
    if (options.json) {
        nlohmann::ordered_json values = nlohmann::ordered_json::object();
        for (const auto& [p, raw] : written->written) values[p->name] = {{"raw", raw}, {"unit", unit(*p)}};
        fmt::print("{}\n", nlohmann::ordered_json{{"unit", connected->device.unit}, {"device", connected->device.profile->id}, {"written", values}, {"requests", written->requests}}.dump());
    } else {
        for (const auto& [p, raw] : written->written) {
            // The value as the device now holds it (what a read would show: "100 °C" for a typed
            // "0100.000"), not the text as typed.
            auto given = std::find_if(resolved.begin(), resolved.end(), [p = p](const auto& r) { return r.first == p; });
            const auto decoded = device::decode_value(*p, raw, written->known);
            const auto text = decoded ? device::format_value(*p, *decoded, written->known) : Result<std::string>(decoded.error());
            const std::string shown = unit(*p);
            fmt::print("wrote {} = {} {}(raw {})\n", p->name, text ? *text : given->second, shown.empty() ? "" : shown + " ", raw);
        }
        fmt::print("{} parameter(s) in {} request(s)\n", written->written.size(), written->requests);
    }
    return exit_ok;
}

}  // namespace loopwire::app
