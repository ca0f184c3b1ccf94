#include "app/monitor_output.hpp"

#include <algorithm>
#include <cmath>
#include <variant>

#include <fmt/format.h>

#include "common/time_text.hpp"
#include "profile/value_format.hpp"

namespace loopwire::app {
namespace {

nlohmann::ordered_json value_entry(const device::WatchedDevice& device, const device::WatchedValue& value, device::MonitorClock::time_point now) {
    const auto& p = *value.parameter;
    nlohmann::ordered_json entry{{"value", nullptr}, {"text", nullptr}, {"unit", device::shown_unit(p, value.last ? &*value.last : nullptr)}, {"status", device::value_status(device, value)}};
    if (value.fresh) {
        entry["value"] = device::value_json(p, *value.last)["value"];
        entry["text"] = device::value_text(p, *value.last);
    }
    const auto age = device::age_seconds(value, now);
    entry["age"] = age ? nlohmann::ordered_json(std::round(*age * 1000.0) / 1000.0) : nlohmann::ordered_json(nullptr);
    entry["changed"] = value.changed;
    if (!value.fresh) entry["error"] = value.error;
    return entry;
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

// A value in a special state is logged by the state's name: a number would pass for a reading.
std::string csv_value(const device::Parameter& parameter, const device::EngineeringValue& value) {
    if (std::holds_alternative<std::monostate>(value.value) && value.status != "ok") return value.status;
    return device::value_text(parameter, value);
}

std::string age_text(const device::WatchedValue& value, device::MonitorClock::time_point now) {
    const auto age = device::age_seconds(value, now);
    if (!age) return "never";
    return fmt::format("{:.1f}s", *age);
}

std::optional<double> retry_in(const device::WatchedDevice& device, device::MonitorClock::time_point now) {
    if (!device.next_try) return std::nullopt;
    const double seconds = std::chrono::duration<double>(*device.next_try - now).count();
    return std::round(std::max(seconds, 0.0) * 1000.0) / 1000.0;
}

// "tc10@3  ok  errors 0", or for a unit in trouble also when it is tried next and why.
std::string device_line(const device::WatchedDevice& device, device::MonitorClock::time_point now) {
    std::string line = fmt::format("{}  {}  errors {}", device.label, device.status, device.errors);
    if (const auto retry = retry_in(device, now)) line += fmt::format("  retry in {:.1f}s", *retry);
    if (device.status != "ok") line += "  " + device.last_error.substr(0, 60);
    return line;
}

}  // namespace

nlohmann::ordered_json sample_json(const device::SampleView& sample, TimeStyle time) {
    nlohmann::ordered_json devices = nlohmann::ordered_json::object();
    for (const auto& device : *sample.devices) {
        nlohmann::ordered_json values = nlohmann::ordered_json::object();
        for (const auto& value : device.values) values[value.parameter->name] = value_entry(device, value, sample.now);
        devices[device.label] = {{"status", device.status}, {"errors", device.errors}};
        if (device.status != "ok") devices[device.label]["error"] = device.last_error;
        if (const auto retry = retry_in(device, sample.now)) devices[device.label]["retry_in"] = *retry;
        devices[device.label]["values"] = values;
    }
    return {{"time", iso8601(sample.time, time == TimeStyle::utc)}, {"sample", sample.index}, {"devices", devices}};
}

std::string csv_header(const std::vector<device::WatchedDevice>& devices) {
    std::vector<std::string> columns{"time", "sample"};
    for (const auto& device : devices) {
        columns.push_back(csv_field(device.label + " status"));
        columns.push_back(csv_field(device.label + " errors"));
        for (const auto& value : device.values) {
            // The fixed unit, else the one the device's configuration words gave its latest value
            // (unit_from: °C or °F on a TC10). A header written before any value was read has
            // none there; FileSampleSink matches such columns whatever unit they carry.
            std::string unit = device::shown_unit(*value.parameter, value.last ? &*value.last : nullptr);
            if (unit == device::unknown_unit) unit.clear();
            columns.push_back(csv_field(device.label + ":" + value.parameter->name + (unit.empty() ? "" : " [" + unit + "]")));
        }
    }
    return fmt::format("{}\n", fmt::join(columns, ","));
}

std::string csv_row(const device::SampleView& sample, TimeStyle time) {
    std::vector<std::string> fields{iso8601(sample.time, time == TimeStyle::utc), std::to_string(sample.index)};
    for (const auto& device : *sample.devices) {
        fields.push_back(device.status);
        fields.push_back(std::to_string(device.errors));
        for (const auto& value : device.values) {
            fields.push_back(value.fresh ? csv_field(csv_value(*value.parameter, *value.last)) : "");
        }
    }
    return fmt::format("{}\n", fmt::join(fields, ","));
}

std::vector<std::string> table_lines(const device::SampleView& sample, TimeStyle time, std::size_t name_width) {
    std::vector<std::string> lines;
    lines.push_back(fmt::format("loopwire monitor  {}  sample {}  (Ctrl-C to stop)", iso8601(sample.time, time == TimeStyle::utc), sample.index));
    lines.push_back(fmt::format("  {:<{}} {:>14} {:<6} {:<14} {:>8}", "PARAMETER", name_width, "VALUE", "UNIT", "STATUS", "AGE"));
    for (const auto& device : *sample.devices) {
        lines.push_back(device_line(device, sample.now));
        for (const auto& value : device.values) {
            const auto& p = *value.parameter;
            const std::string text = value.last ? device::value_text(p, *value.last) : "-";
            // Bold for a value that just changed; dim for one not read this sample (its status
            // and age say why), so an old value never passes for a current one.
            const char* style = value.changed ? "\x1b[1m" : value.fresh ? "" : "\x1b[2m";
            const std::string name = p.name.size() > name_width ? p.name.substr(0, name_width - 1) + "~" : p.name;
            lines.push_back(fmt::format("  {:<{}} {}{:>14}\x1b[0m {:<6} {:<14} {:>8}", name, name_width, style, text,
                                        device::shown_unit(p, value.last ? &*value.last : nullptr),
                                        device::value_status(device, value), age_text(value, sample.now)));
        }
    }
    return lines;
}

std::string table_frame(const std::vector<std::string>& lines, std::size_t previous_line_count) {
    std::string frame = previous_line_count == 0 ? "\x1b[?25l" : fmt::format("\x1b[{}F", previous_line_count);
    for (const auto& line : lines) frame += "\r" + line + "\x1b[K\n";
    frame += "\x1b[J";  // a shorter frame than the last leaves nothing of it below
    return frame;
}

Result<MonitorFormat> monitor_format(std::string_view option, bool terminal) {
    if (option.empty()) return terminal ? MonitorFormat::table : MonitorFormat::jsonl;
    if (option == "table") return MonitorFormat::table;
    if (option == "jsonl") return MonitorFormat::jsonl;
    if (option == "csv") return MonitorFormat::csv;
    return make_error(ErrorKind::usage, fmt::format("--format '{}': choose table, csv or jsonl", option));
}

StreamSampleSink::~StreamSampleSink() {
    if (format_ == MonitorFormat::table) {
        std::fputs(terminal_restore, out_);
        std::fflush(out_);
    }
}

std::string sample_line(const device::SampleView& sample, MonitorFormat format, TimeStyle time, bool with_csv_header) {
    if (format == MonitorFormat::jsonl) return sample_json(sample, time).dump() + "\n";
    if (format == MonitorFormat::csv) return (with_csv_header ? csv_header(*sample.devices) : "") + csv_row(sample, time);
    return table_frame(table_lines(sample, time), 0);
}

void StreamSampleSink::write(const device::SampleView& sample) {
    std::string text;
    if (format_ != MonitorFormat::table) text = sample_line(sample, format_, time_, sample.index == 1);
    else {
        const auto lines = table_lines(sample, time_);
        text = table_frame(lines, shown_lines_);
        shown_lines_ = lines.size();
    }
    std::fputs(text.c_str(), out_);
    std::fflush(out_);
}

}  // namespace loopwire::app
