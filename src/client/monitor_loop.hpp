#pragma once
// The polling loop of `loopwire monitor`, apart from option parsing, so `loopwire demo` can run
// it on simulators inside the process: it takes masters that are already open.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <optional>
#include <stop_token>
#include <vector>

#include "client/monitor_state.hpp"
#include "client/device_client.hpp"
#include "session/master.hpp"

namespace loopwire::device {

struct MonitorTarget {
    session::Master* master = nullptr;  // shared by targets on the same link
    device::DeviceAddress device;
    std::vector<const device::Parameter*> parameters;
    // When set, the device's back-off lives with whoever carries its requests (the gateway's
    // line scheduler, gateway/line_scheduler.hpp): before each poll the poller asks this, skips
    // the device while it names a time, and keeps no back-off of its own, so the two cannot
    // compound. Unset (`loopwire monitor`): the poller's own back-off, as described below.
    std::function<std::optional<MonitorClock::time_point>()> held_until;
    // Whether the poller checks the unit is the device named (client/identity_check.hpp): its
    // profile's identification words are read with the first poll and the first after every
    // outage, and a unit that answers as another device is `wrong-device`, none of its words
    // taken for values. `loopwire monitor --no-identify` and the gateway's `identify = false`.
    bool identify = true;
};

// One sample as the poller hands it to its sinks: every watched device with its values.
struct SampleView {
    unsigned index = 0;                           // 1-based
    std::chrono::system_clock::time_point time;   // when the sample started
    MonitorClock::time_point now;                 // the same instant, for ages
    const std::vector<WatchedDevice>* devices = nullptr;
    // Slots of the schedule skipped just before this sample because the one before ran past
    // them (0 when on time): the polls could not keep their interval.
    unsigned missed = 0;
};

// What consumes samples: CSV and JSON-lines files (client/monitor_file.hpp), the CLI's terminal
// table (app/monitor_output.hpp) and the gateway's fronts. Called on the poller's thread, once
// per sample, in order.
class SampleSink {
public:
    virtual ~SampleSink() = default;
    virtual void write(const SampleView& sample) = 0;
};

// The fixed schedule samples start on: slot k at start + k x interval. A sample that ends past
// the next slot skips the slots it missed rather than bunching up.
class SampleSchedule {
public:
    SampleSchedule(MonitorClock::time_point start, std::chrono::milliseconds interval) : start_(start), interval_(interval) {}

    struct Next {
        MonitorClock::time_point at;  // when the next sample starts
        unsigned missed = 0;          // slots skipped before it
    };
    // After a sample that ended at `now`.
    Next after(MonitorClock::time_point now);

private:
    MonitorClock::time_point start_;
    std::chrono::milliseconds interval_;
    std::int64_t slot_ = 0;  // of the sample that just ran
};

struct MonitorSettings {
    std::chrono::milliseconds interval{1000};
    std::optional<unsigned> count;  // stop after this many samples
    std::chrono::milliseconds backoff_cap{30000};
};

// Polls every target once per interval (samples start on a fixed schedule; a late sample skips
// the slots it missed rather than bunching up, and counts them in each device's `missed` and
// the next sample's `missed`), and hands each sample to `sink`. A target that
// does not answer is retried with exponential back-off (RetryBackoff: first wait one interval,
// doubling up to backoff_cap), and each poll of it stops at its first timeout, so a dead unit
// costs at most one timeout per back-off period. A poll that fails because the link failed
// shows the device as "line-down", not "no-reply": the device is not to blame (with held_until
// it does not back the device off either; the link has its own reopen schedule). Returns when
// `count` samples were taken or `stop` is requested.
void run_monitor(const std::vector<MonitorTarget>& targets, const MonitorSettings& settings, SampleSink& sink,
                 std::stop_token stop);

// The one poll loop of every monitor (named parameters above, raw registers in
// client/register_monitor.hpp): samples start on the fixed schedule of `settings.interval`; each
// runs `poll` (given the slots missed just before it), then, unless `stop` came meanwhile,
// `write` (given the sample's 1-based index, its wall-clock start and the slots missed). Returns
// when `settings.count` samples were written or `stop` is requested.
struct SampleSteps {
    std::function<void(unsigned missed)> poll;
    std::function<void(unsigned index, std::chrono::system_clock::time_point time, unsigned missed)> write;
};
void run_sample_schedule(const MonitorSettings& settings, const SampleSteps& steps, const std::stop_token& stop);

}  // namespace loopwire::device
