#include "client/monitor_records.hpp"

#include <algorithm>
#include <cmath>
#include <variant>

#include <fmt/format.h>

#include "client/device_status.hpp"
#include "common/time_text.hpp"
#include "profile/value_format.hpp"

namespace loopwire::device {
namespace {

nlohmann::ordered_json value_entry(const WatchedDevice& device, const WatchedValue& value, MonitorClock::time_point now) {
    const auto& p = *value.parameter;
    nlohmann::ordered_json entry{{"value", nullptr}, {"text", nullptr}, {"unit", shown_unit(p, value.last ? &*value.last : nullptr)}, {"status", value_status(device, value)}};
    if (value.fresh) {
        entry["value"] = value_json(p, *value.last)["value"];
        entry["text"] = value_text(p, *value.last);
    }
    const auto age = age_seconds(value, now);
    entry["age"] = age ? nlohmann::ordered_json(std::round(*age * 1000.0) / 1000.0) : nlohmann::ordered_json(nullptr);
    entry["changed"] = value.changed;
    if (!value.fresh) entry["error"] = value.error;
    return entry;
}

// A value in a special state is logged by the state's name: a number would pass for a reading.
std::string csv_value(const Parameter& parameter, const EngineeringValue& value) {
    if (std::holds_alternative<std::monostate>(value.value) && value.status != "ok") return value.status;
    return value_text(parameter, value);
}

}  // namespace

std::optional<double> retry_in(const WatchedDevice& device, MonitorClock::time_point now) {
    if (!device.next_try) return std::nullopt;
    const double seconds = std::chrono::duration<double>(*device.next_try - now).count();
    return std::round(std::max(seconds, 0.0) * 1000.0) / 1000.0;
}

nlohmann::ordered_json sample_json(const SampleView& sample, TimeStyle time) {
    nlohmann::ordered_json devices = nlohmann::ordered_json::object();
    for (const auto& device : *sample.devices) {
        nlohmann::ordered_json values = nlohmann::ordered_json::object();
        for (const auto& value : device.values) values[value.parameter->name] = value_entry(device, value, sample.now);
        devices[device.label] = {{"status", status_text(device.status)}, {"errors", device.errors}};
        if (device.status != DeviceStatus::ok) devices[device.label]["error"] = device.last_error;
        if (const auto retry = retry_in(device, sample.now)) devices[device.label]["retry_in"] = *retry;
        devices[device.label]["values"] = values;
    }
    return {{"time", iso8601(sample.time, time == TimeStyle::utc)}, {"sample", sample.index}, {"devices", devices}};
}

std::string csv_header(const std::vector<WatchedDevice>& devices) {
    std::vector<std::string> columns{"time", "sample"};
    for (const auto& device : devices) {
        columns.push_back(csv_field(device.label + " status"));
        columns.push_back(csv_field(device.label + " errors"));
        for (const auto& value : device.values) {
            // The fixed unit, else the one the device's configuration words gave its latest value
            // (unit_from: °C or °F on a TC10). A header written before any value was read has
            // none there; FileSampleSink matches such columns whatever unit they carry.
            std::string unit = shown_unit(*value.parameter, value.last ? &*value.last : nullptr);
            if (unit == unknown_unit) unit.clear();
            columns.push_back(csv_field(device.label + ":" + value.parameter->name + (unit.empty() ? "" : " [" + unit + "]")));
        }
    }
    return fmt::format("{}\n", fmt::join(columns, ","));
}

std::string csv_row(const SampleView& sample, TimeStyle time) {
    std::vector<std::string> fields{iso8601(sample.time, time == TimeStyle::utc), std::to_string(sample.index)};
    for (const auto& device : *sample.devices) {
        fields.emplace_back(status_text(device.status));
        fields.push_back(std::to_string(device.errors));
        for (const auto& value : device.values) {
            fields.push_back(value.fresh ? csv_field(csv_value(*value.parameter, *value.last)) : "");
        }
    }
    return fmt::format("{}\n", fmt::join(fields, ","));
}

Result<MonitorFormat> monitor_format(std::string_view option, bool terminal) {
    if (option.empty()) return terminal ? MonitorFormat::table : MonitorFormat::jsonl;
    if (option == "table") return MonitorFormat::table;
    if (option == "jsonl") return MonitorFormat::jsonl;
    if (option == "csv") return MonitorFormat::csv;
    return make_error(ErrorKind::usage, fmt::format("--format '{}': choose table, csv or jsonl", option));
}

// RFC 4180: quote a field holding a comma, a quote or a line break; double inner quotes.
std::string csv_field(const std::string& text) {
    if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
    std::string quoted = "\"";
    for (char c : text) {
        if (c == '"') quoted += '"';
        quoted += c;
    }
    return quoted + "\"";
}

std::string record_line(const SampleView& sample, MonitorFormat format, TimeStyle time, bool with_csv_header) {
    if (format == MonitorFormat::csv) return (with_csv_header ? csv_header(*sample.devices) : "") + csv_row(sample, time);
    return sample_json(sample, time).dump() + "\n";
}

}  // namespace loopwire::device
