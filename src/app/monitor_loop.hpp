#pragma once
// The polling loop of `loopwire monitor`, apart from option parsing, so `loopwire demo` can run
// it on simulators inside the process: it takes masters that are already open.
#include <chrono>
#include <cstdio>
#include <optional>
#include <stop_token>
#include <vector>

#include "app/monitor_output.hpp"
#include "device/device_client.hpp"
#include "session/master.hpp"

namespace loopwire::app {

struct MonitorTarget {
    session::Master* master = nullptr;  // shared by targets on the same link
    device::DeviceAddress device;
    std::vector<const device::Parameter*> parameters;
};

struct MonitorSettings {
    std::chrono::milliseconds interval{1000};
    std::optional<unsigned> count;  // stop after this many samples
    MonitorFormat format = MonitorFormat::jsonl;
    std::chrono::milliseconds backoff_cap{30000};
};

// Polls every target once per interval (samples start on a fixed schedule; a late sample skips
// the slots it missed rather than bunching up), and writes each sample to `out`. A target that
// does not answer is retried with exponential back-off (RetryBackoff: first wait one interval,
// doubling up to backoff_cap), and each poll of it stops at its first timeout, so a dead unit
// costs at most one timeout per back-off period. Returns when `count` samples were taken or
// `stop` is requested; the table format always leaves the cursor shown and attributes reset.
void run_monitor(const std::vector<MonitorTarget>& targets, const MonitorSettings& settings, std::FILE* out,
                 std::stop_token stop);

}  // namespace loopwire::app
