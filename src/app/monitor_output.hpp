#pragma once
// How monitor samples are shown: a live table redrawn in place on a terminal, or one line per
// sample as CSV or JSON lines for files and pipes.
#include <chrono>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/monitor_state.hpp"

namespace loopwire::app {

enum class MonitorFormat { table, csv, jsonl };

struct SampleView {
    unsigned index = 0;                           // 1-based
    std::chrono::system_clock::time_point time;   // when the sample started
    MonitorClock::time_point now;                 // the same instant, for ages
    const std::vector<WatchedDevice>* devices = nullptr;
};

// {"time":"...Z","sample":1,"devices":{"tc10@3":{"status":"ok","errors":0,"values":{NAME:
// {"value":V,"text":"25.0","unit":"°C","status":"ok","age":0.0,"changed":false}}}}}.
// A value not read in this sample has "value":null and "text":null whatever was read before;
// "age" says how old the last good reading is (null: never read), "status" why it is missing.
// A device whose status is not "ok" also has "error" (the last failure) and, while in back-off,
// "retry_in" (seconds until it is tried again).
nlohmann::ordered_json sample_json(const SampleView& sample);

// CSV: time,sample, then per device "DEVICE status","DEVICE errors", and one column
// "DEVICE:NAME" per value holding its text, empty when not read in this sample.
std::string csv_header(const std::vector<WatchedDevice>& devices);
std::string csv_row(const SampleView& sample);

// The table for one sample, one line per element (no newlines, no cursor movement): a title,
// a header, then per device a line with its status and error count and a line per value with
// value, unit, status and age. Changed values are bold; values not read this sample are dim.
std::vector<std::string> table_lines(const SampleView& sample);

// Terminal control around table_lines: the first frame hides the cursor; each later frame moves
// back up over the previous one and overwrites it line by line, so the screen never scrolls.
std::string table_frame(const std::vector<std::string>& lines, std::size_t previous_line_count);
// Shows the cursor and resets attributes: printed however the monitor ends.
inline constexpr const char* terminal_restore = "\x1b[0m\x1b[?25h";

}  // namespace loopwire::app
