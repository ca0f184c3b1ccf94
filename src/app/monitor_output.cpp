#include "app/monitor_output.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "client/device_status.hpp"
#include "common/time_text.hpp"
#include "profile/value_format.hpp"

namespace loopwire::app {
namespace {

std::string age_text(const device::WatchedValue& value, device::MonitorClock::time_point now) {
    const auto age = device::age_seconds(value, now);
    if (!age) return "never";
    return fmt::format("{:.1f}s", *age);
}

// "tc10@3  ok  errors 0", or for a unit in trouble also when it is tried next and why.
std::string device_line(const device::WatchedDevice& device, device::MonitorClock::time_point now) {
    std::string line =
        fmt::format("{}  {}  errors {}", device.label, device::status_text(device.status), device.errors);
    if (const auto retry = device::retry_in(device, now)) line += fmt::format("  retry in {:.1f}s", *retry);
    if (device.status != device::DeviceStatus::ok) line += "  " + device.last_error.substr(0, 60);
    return line;
}

}  // namespace

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

StreamSampleSink::~StreamSampleSink() {
    if (format_ == MonitorFormat::table) {
        std::fputs(terminal_restore, out_);
        std::fflush(out_);
    }
}

std::string sample_line(const device::SampleView& sample, MonitorFormat format, TimeStyle time, bool with_csv_header) {
    if (format != MonitorFormat::table) return device::record_line(sample, format, time, with_csv_header);
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
