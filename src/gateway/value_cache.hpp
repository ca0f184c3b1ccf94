#pragma once
// The gateway's value cache: the last values its polls read from every device, with status and
// sample time, which every front reads (snapshot), and a stream of the changes (subscribe),
// which MQTT, HTTP and the history store consume (docs/DESIGN.md, gateway).
//
// Threads: the devices are updated by the polls' thread (gateway/poll_groups.hpp); the cache
// still takes updates from several threads at once. A subscriber's callback runs on the thread
// whose update changed something, so it must be quick (copy the change, queue it, return): every
// poll waits for it. Callbacks of one subscriber never run at the same time, and the changes of one
// device reach it in the order they happened. A callback may read snapshot(), subscribe, and
// end its own subscription; it must not throw.
//
// Staleness: a device polled every T whose last poll answered is `stale` once that poll is more
// than T + 2T old, that is once the next poll, due after T, is overdue by more than two
// intervals. Its values then read `stale` everywhere: in snapshot() at once (it is worked out
// from the clock when read), and for subscribers (MQTT, the history, server-sent events) when
// mark_overdue() finds it, which the poll groups call on a timer of their own (poll_groups.hpp):
// a device's poll that never completes (a line too busy to carry it) tells nothing by itself.
// Its next poll makes it `ok` again. A device whose polls get no answer is not stale but
// `no-reply`: it shows no value to be stale.
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "client/monitor_state.hpp"
#include "client/resolved_value.hpp"
#include "common/clock.hpp"

namespace loopwire::gateway {

// How far past its due time a device's poll may be before its values are `stale`: two
// intervals (the header says why the count starts at the due time, one interval after the poll).
constexpr int overdue_intervals_allowed = 2;

// One device as the last poll found it, or `stale` when that poll is overdue (above).
struct CachedDevice {
    std::string name;             // the configured device name
    device::WatchedDevice state;  // values, status (ok, no_reply, stale, ...), errors
    std::chrono::system_clock::time_point sampled;
    std::chrono::milliseconds interval{0};  // how often it is polled; 0 when not declared
    // Since its last poll that answered, on the cache's clock; none before one, and after a
    // poll that got no answer.
    std::optional<std::chrono::milliseconds> since_answered;
    // The cache's clock (the engine's, which the polls stamp their reads with) when this view
    // was taken: what the values' ages are measured to (resolved_view), never a front's clock.
    Instant seen_at{};
};

// One of the device's values as every front shows it (client/resolved_value.hpp): its text,
// decimals, unit, limits, status and age as of the view.
inline device::ResolvedValue resolved_view(const CachedDevice& device, const device::WatchedValue& value) {
    return device::resolve_watched(device.state, value, device.seen_at);
}

// What the polls last found of a device, as snapshot() would say it: its status, and why it is
// not `ok`.
struct DeviceSeen {
    device::DeviceStatus status = device::DeviceStatus::waiting;
    std::string error;
};
// Looks a device up by its configured name; none before its first poll. It reads the cache
// through a weak hold: once the cache is gone, every device is none.
using DeviceLookup = std::function<std::optional<DeviceSeen>(const std::string& name)>;

// A parameter whose value or status changed, or a device whose status changed.
struct ValueChange {
    std::string device;     // the configured device name
    std::string parameter;  // the parameter's name; empty when this is the device's own status
    // The value read in this sample; none when it was not read (status and error say why).
    std::optional<device::EngineeringValue> value;
    std::string text;  // the value as people read it ("137.0", an enum label); empty with no value
    int decimals = 0;  // the digits after the point `text` shows (device::ResolvedValue::decimals)
    std::string unit;  // "°C"; empty for the device's status
    // A number's limits in engineering units as the device holds them, with the one fallback
    // (device::ResolvedValue::limits): what the API, /meta, Sparkplug and Home Assistant show.
    device::ValueLimits limits = {};
    // A value's: "ok", its special state ("under-range", ...), "no-reply", "error" or "stale"
    // (device::value_status). The device's: the text of device_status. A stale value carries no
    // value: the last one read is no longer known to be the device's.
    std::string status;
    // The device's status, when this is about the device (its text is `status`).
    device::DeviceStatus device_status = device::DeviceStatus::waiting;
    // Why there is no value, or why the device is not "ok".
    std::string error;
    // When the poll's reply (or its failure) reached the gateway; for a change to `stale`, when
    // it was found stale. The changes of one device are told in the order of these stamps, each
    // later than the one before (ValueCache::update), so a history of them is ordered by them.
    std::chrono::system_clock::time_point sampled;

    bool about_device() const { return parameter.empty(); }
};

using ValueCallback = std::function<void(const ValueChange&)>;

namespace detail {
struct ValueHub;
struct ValueSubscriber;
}  // namespace detail

// Ends its subscription when destroyed or reset: from then on the callback is not called, and
// a call running on another thread has returned. It may outlive the cache.
class ValueSubscription {
public:
    ValueSubscription() = default;
    ~ValueSubscription();
    ValueSubscription(ValueSubscription&& other) noexcept = default;
    ValueSubscription& operator=(ValueSubscription&& other) noexcept;
    ValueSubscription(const ValueSubscription&) = delete;
    ValueSubscription& operator=(const ValueSubscription&) = delete;

    void reset();
    bool active() const { return subscriber_ != nullptr; }

private:
    friend class ValueCache;
    ValueSubscription(std::weak_ptr<detail::ValueHub> hub, std::shared_ptr<detail::ValueSubscriber> subscriber);

    std::weak_ptr<detail::ValueHub> hub_;
    std::shared_ptr<detail::ValueSubscriber> subscriber_;
};

class ValueCache {
public:
    using WallClock = std::function<std::chrono::system_clock::time_point()>;
    // `clock`: what staleness is measured on; `wall`: what a change to `stale` is stamped with
    // (empty: the system clock). Tests inject virtual ones.
    explicit ValueCache(std::shared_ptr<Clock> clock = steady_clock(), WallClock wall = {});
    ~ValueCache();
    ValueCache(const ValueCache&) = delete;
    ValueCache& operator=(const ValueCache&) = delete;

    // Device `name` is polled every `interval`: from now on its values go stale when its poll
    // is overdue (above). A device never declared never goes stale.
    void expect_polls(const std::string& name, std::chrono::milliseconds interval);

    // One sample of the device named `name`, `sampled` when its reply came. Changes against its
    // last polled state go to the subscribers, on this thread: on its first sample every
    // parameter and the device's status. A device in back-off ("waiting": not polled this
    // sample) changes nothing but the snapshot. A device's changes are stamped later than the
    // ones told of it before, a `stale` among them: a stamp that is not (the same millisecond, a
    // clock set back) is moved to 1 ms after the last, so that whoever files the changes by
    // their stamp (the history) never files a reply's `ok` before the `stale` it ended.
    void update(const std::string& name, const device::WatchedDevice& state,
                std::chrono::system_clock::time_point sampled);

    // Every device that became stale since the last call is told to the subscribers as
    // `stale`, on this thread. Returns the names of the devices stale now.
    std::vector<std::string> mark_overdue();

    std::vector<CachedDevice> snapshot() const;  // in the order devices were first seen

    // Reads one device's status as snapshot() would, for the write policy
    // (gateway/device_writer.hpp); it may outlive the cache (above).
    DeviceLookup device_lookup() const;

    // What the subscribers were last told of device `name`: its status, then each parameter, as
    // one whole sample (an update is told whole before the next one starts, so this is never
    // half of one); empty before its first sample. A subscriber that must act on a device's
    // whole picture (a Sparkplug birth) reads it here rather than piecing it together from its
    // callbacks, which may be in the middle of one update's changes.
    std::vector<ValueChange> told(const std::string& name) const;

    // Calls `callback` with the state of every device polled so far (its status, then each
    // parameter), on this thread before returning, then with every change after it: a
    // subscriber that starts empty holds the full picture whenever it joins.
    [[nodiscard]] ValueSubscription subscribe(ValueCallback callback);

private:
    std::shared_ptr<detail::ValueHub> hub_;
};

}  // namespace loopwire::gateway
