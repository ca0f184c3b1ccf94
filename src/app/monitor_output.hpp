#pragma once
// How monitor samples are shown: a live table redrawn in place on a terminal, or one line per
// sample as CSV or JSON lines (client/monitor_records.hpp) for pipes.
#include <chrono>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "client/monitor_records.hpp"

namespace loopwire::app {

using device::MonitorFormat;
using device::TimeStyle;
using device::csv_header;
using device::csv_row;
using device::monitor_format;
using device::sample_json;

// The text a sample adds to a stream: a JSON line, a CSV row (after the header when asked),
// or a table frame.
std::string sample_line(const device::SampleView& sample, MonitorFormat format, TimeStyle time, bool with_csv_header);

// The table for one sample, one line per element (no newlines, no cursor movement): a title,
// a header, then per device a line with its status and error count and a line per value with
// value, unit, status and age. Changed values are bold; values not read this sample are dim.
// `name_width` is the PARAMETER column's width; a longer name is cut, ending in "~".
std::vector<std::string> table_lines(const device::SampleView& sample, TimeStyle time = TimeStyle::utc, std::size_t name_width = 34);

// Terminal control around table_lines: the first frame hides the cursor; each later frame moves
// back up over the previous one and overwrites it line by line, so the screen never scrolls.
std::string table_frame(const std::vector<std::string>& lines, std::size_t previous_line_count);
// Shows the cursor and resets attributes: printed however the monitor ends.
inline constexpr const char* terminal_restore = "\x1b[0m\x1b[?25h";

// Writes each sample to a stdio stream in one of the formats above, flushed per sample; the
// table format leaves the cursor shown and attributes reset when the sink is destroyed.
class StreamSampleSink final : public device::SampleSink {
public:
    StreamSampleSink(std::FILE* out, MonitorFormat format, TimeStyle time = TimeStyle::utc)
        : out_(out), format_(format), time_(time) {}
    ~StreamSampleSink() override;
    StreamSampleSink(const StreamSampleSink&) = delete;
    StreamSampleSink& operator=(const StreamSampleSink&) = delete;

    void write(const device::SampleView& sample) override;

private:
    std::FILE* out_;
    MonitorFormat format_;
    TimeStyle time_;
    std::size_t shown_lines_ = 0;
};

}  // namespace loopwire::app
