#pragma once
// Monitor samples as records for files and pipes: one line per sample as CSV or JSON lines,
// written by the file sinks (client/monitor_file.hpp) and by `loopwire monitor` on a pipe.
#include <chrono>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "client/monitor_loop.hpp"

namespace loopwire::device {

// How a monitor shows its samples: the live table (a terminal only), CSV or JSON lines.
enum class MonitorFormat { table, csv, jsonl };

// How sample times are written: local time with its offset (the monitor's default) or UTC
// (--utc), both ISO 8601.
enum class TimeStyle { local, utc };

// The format a --format option names; empty chooses the table on a terminal, JSON lines otherwise.
Result<MonitorFormat> monitor_format(std::string_view option, bool terminal);

// {"time":"...Z","sample":1,"devices":{"tc10@3":{"status":"ok","errors":0,"values":{NAME:
// {"value":V,"text":"25.0","unit":"°C","status":"ok","age":0.0,"changed":false}}}}}.
// A value not read in this sample has "value":null and "text":null whatever was read before;
// "age" says how old the last good reading is (null: never read), "status" why it is missing.
// A device whose status is not "ok" also has "error" (the last failure) and, while in back-off,
// "retry_in" (seconds until it is tried again).
nlohmann::ordered_json sample_json(const SampleView& sample, TimeStyle time = TimeStyle::utc);

// CSV: time,sample, then per device "DEVICE status","DEVICE errors", and one column
// "DEVICE:NAME [UNIT]" per value ("tc10@3:measured_value [°C]"; no brackets for a value without
// unit) holding its text, or the name of its special state ("out-of-range", "under-range": the
// state, not an empty cell, reaches the log); empty when not read in this sample.
std::string csv_header(const std::vector<WatchedDevice>& devices);
std::string csv_row(const SampleView& sample, TimeStyle time = TimeStyle::utc);

// One CSV field as RFC 4180 writes it: quoted when it holds a comma, a quote or a line break,
// inner quotes doubled.
std::string csv_field(const std::string& text);

// The text a sample adds to a CSV (after the header when asked) or JSON-lines stream; `format`
// is csv or jsonl.
std::string record_line(const SampleView& sample, MonitorFormat format, TimeStyle time, bool with_csv_header);

// Seconds until a device in back-off is tried again, to the millisecond; nothing when it is not
// waiting.
std::optional<double> retry_in(const WatchedDevice& device, MonitorClock::time_point now);

}  // namespace loopwire::device
