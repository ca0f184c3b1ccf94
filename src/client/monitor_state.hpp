#pragma once
// What `loopwire monitor` knows about each device between samples: the last good value of every
// watched parameter and when it was read, whether the device answers, and how often it failed.
#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "client/device_client.hpp"
#include "client/device_status.hpp"

namespace loopwire::device {

using MonitorClock = std::chrono::steady_clock;

struct WatchedValue {
    const device::Parameter* parameter = nullptr;
    std::optional<device::EngineeringValue> last;  // the last value read, kept to show its age
    std::optional<MonitorClock::time_point> read_at;
    bool fresh = false;    // read in the latest sample
    bool changed = false;  // fresh, and its raw word differs from the value before
    std::string error;     // why it is not fresh, when it is not
};

// Its status (client/device_status.hpp) says whether the latest poll read everything, part, or
// nothing and why; the gateway alone sets `stale` (gateway/value_cache.hpp).
struct WatchedDevice {
    std::string label;  // "tc10@3"
    std::vector<WatchedValue> values;
    DeviceStatus status = DeviceStatus::waiting;
    unsigned errors = 0;  // failed polls so far
    unsigned polls = 0;
    // Samples of the fixed schedule it missed: the sample before ran past their start.
    unsigned missed = 0;
    std::string last_error;
    std::optional<MonitorClock::time_point> next_try;  // while in back-off: when it is tried again
    // Every word the polls read, dependencies included (decimal points, unit words, the words
    // that bound others), as last read: what the values' limits are resolved from.
    device::RawValues known;
    // Set when the poller checks the device is the one named: the profile whose identification
    // words its polls read (identity_words_due) until they hold, at start and after every outage.
    const device::Profile* identified_as = nullptr;
    bool identity_confirmed = false;
};

WatchedDevice watch(std::string label, const std::vector<const device::Parameter*>& parameters,
                    const device::Profile* identify_as = nullptr);

// The identification words the device's next poll must read beside its parameters: the
// profile's, while the device has not shown since its last outage that it is that device; none
// when it has or is not checked.
std::vector<const device::Parameter*> identity_words_due(const WatchedDevice& device);

// `parameters` and the identification words due (identity_words_due), each once.
std::vector<const device::Parameter*> with_identity_words(std::vector<const device::Parameter*> parameters,
                                                          const WatchedDevice& device);

// Folds one poll into the device's state. `answered` is false when the device did not answer at
// all (timeout, link failure): its values then keep their last reading but are not fresh.
void record_poll(WatchedDevice& device, const device::ReadReport& report, bool answered, const std::string& failure,
                 MonitorClock::time_point now);

// The poll could not reach the device: its link failed or is down (`failure` says which and
// why). Like a poll without a reply, but the device is not to blame.
void record_line_down(WatchedDevice& device, const std::string& failure);

// Folds a whole poll into the device's state: `stopped_by` is the timeout (no reply) or link
// failure (line down) that ended it, if one did. Exception 0Ah or 0Bh is a gateway on the way
// saying the device did not answer it (Modbus Application Protocol 1.1b, section 7): `no-reply`,
// not a device that answered part. A poll that read identification words is judged by them
// first: a unit that answers as another device is `wrong-device` and none of its words count. A poll that was never sent (never_sent(): the
// line was busy with other requests until its deadline) learnt nothing of the device: it counts
// as not polled (record_unsent), not as a device that does not answer.
void record_outcome(WatchedDevice& device, const device::ReadReport& report, const std::optional<Error>& stopped_by,
                    MonitorClock::time_point now);

// The device was not polled this sample (back-off): nothing is fresh.
void record_skipped(WatchedDevice& device);

// The sample's poll of the device never went out (`why`): nothing is fresh and the status is
// `waiting`, so whoever keeps the device's picture (gateway/value_cache.hpp) keeps what its last
// poll found, until the staleness watch finds that poll overdue.
void record_unsent(WatchedDevice& device, const std::string& why);

// Seconds since the value was last read, or nothing when it never was.
std::optional<double> age_seconds(const WatchedValue& value, MonitorClock::time_point now);

// A value's status when the device answered but did not give that value (an exception, an
// undecodable word): the value failed, not the device.
inline constexpr std::string_view failed_value_status = "error";

// The status shown for one value: the value's own ("ok", a special state such as
// "under-range") when fresh, else why it is not: the device's status unless its latest poll
// answered and is not overdue ("no-reply", "line-down", "waiting", "stale"), else
// failed_value_status ("error"), which a wrong device's values say too.
std::string value_status(const WatchedDevice& device, const WatchedValue& value);

}  // namespace loopwire::device
