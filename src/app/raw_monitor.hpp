#pragma once
// `loopwire monitor --link URL --unit N TABLE ADDRESS [COUNT] [--type T ...]`: continuous polling
// of raw registers of a device without a profile, typed as `loopwire read` types them
// (raw_registers.hpp), shown as a live table, CSV or JSON lines like the named monitor.
#include <chrono>
#include <cstdio>
#include <stop_token>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/master_options.hpp"
#include "app/monitor_output.hpp"
#include "app/raw_registers.hpp"
#include "client/monitor_file.hpp"
#include "client/monitor_loop.hpp"

namespace loopwire::app {

// One poll of the registers: "ok" with the values, or why there are none ("no-reply" after a
// timeout or a link failure, "exception" for a Modbus exception reply, "error" otherwise).
struct RawSample {
    unsigned index = 0;  // 1-based
    std::chrono::system_clock::time_point time;
    bool utc = false;  // time printed in UTC (...Z) rather than local time with its offset
    std::string status = "ok";
    std::string error;
    std::vector<RawReading> readings;  // empty unless ok
    unsigned errors = 0;               // failed polls so far, this one included
};

// {"time":"...Z","sample":1,"unit":5,"table":"holding","type":"float32","status":"ok",
//  "errors":0,"values":{"100":12.5,"102":-3.25}}: values keyed by address (--base numbering),
// null when not read in this sample; "error" says why when the status is not "ok".
nlohmann::ordered_json raw_sample_json(const RawRequest& request, int unit, const RawSample& sample);

// time,sample,status,errors,"holding 100","holding 102",...: a value is empty when not read.
std::string raw_csv_header(const RawRequest& request);
std::string raw_csv_row(const RawRequest& request, const RawSample& sample);

// The lines of the live table for one sample (no newlines, no cursor movement).
std::vector<std::string> raw_table_lines(const RawRequest& request, int unit, const RawSample& sample);

// Where raw samples go: a log file (appended to and rotated as the named monitor's), or else the
// terminal or pipe.
struct RawOutput {
    std::FILE* terminal = stdout;
    device::FileSampleSink* file = nullptr;
};

// Polls once per settings.interval on the monitors' one loop (client/register_monitor.hpp) until
// settings.count samples were taken or `stop` is requested, writing each sample to `out`. A unit
// that does not answer costs one timeout per sample and shows as "no-reply"; the polling goes on.
void poll_raw(device::Master& master, int unit, const RawRequest& request, unsigned per_request,
              const device::MonitorSettings& settings, MonitorFormat format, bool utc, RawOutput out, std::stop_token stop);

// The whole command once monitor's options are parsed: `arguments` are TABLE ADDRESS [COUNT] or
// REFERENCE [COUNT]; `output.path` a log file to write instead of stdout (empty: stdout), with
// --append and rotation as for named parameters.
int run_raw_monitor(const MasterCommandOptions& master, const RawTypeOptions& typing, const std::vector<std::string>& arguments,
                    const device::MonitorSettings& settings, MonitorFormat format, const device::MonitorFileOptions& output);

}  // namespace loopwire::app
