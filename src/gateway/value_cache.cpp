#include "gateway/value_cache.hpp"

#include <algorithm>
#include <map>
#include <mutex>
#include <utility>

#include <fmt/format.h>

#include "client/resolved_value.hpp"
#include "profile/value_format.hpp"

namespace loopwire::gateway {

// Locking: a subscriber's mutex is held while its callback runs; the hub's guards the devices
// and the list of subscribers and is never held while a callback runs. Where both are taken,
// the subscriber's comes first (a callback reading the snapshot; subscribe()), so they cannot
// deadlock. The hub's `telling` mutex is held by update() and mark_overdue() from working out
// the changes until they are delivered: the poll thread and the staleness timer both change a
// device, and without it a `stale` found just before a poll could reach a subscriber after the
// poll's `ok`. It is taken before the others and never by a callback's calls.
namespace detail {

using SystemTime = std::chrono::system_clock::time_point;

struct ValueSubscriber {
    explicit ValueSubscriber(ValueCallback f) : callback(std::move(f)) {}

    // Recursive: a callback may end its own subscription, which takes this mutex again.
    std::recursive_mutex mutex;
    bool active = true;
    ValueCallback callback;
};

struct DeviceEntry {
    CachedDevice latest;  // as polled; since_answered is filled in by snapshot()
    std::vector<ValueChange> published;  // the device's status, then each parameter, as last told
    std::optional<Instant> answered_at;  // the cache's clock when its last answered poll arrived
    std::optional<SystemTime> told_at;    // the stamp of the last changes told of it
    bool told_stale = false;
};

struct ValueHub {
    ValueHub(std::shared_ptr<Clock> time, std::function<std::chrono::system_clock::time_point()> wall_time)
        : clock(std::move(time)), wall(std::move(wall_time)) {
        if (!wall) wall = [] { return std::chrono::system_clock::now(); };
    }

    const std::shared_ptr<Clock> clock;
    std::function<std::chrono::system_clock::time_point()> wall;
    std::mutex telling;
    std::mutex mutex;
    std::vector<DeviceEntry> devices;  // in the order first seen
    // Declared poll intervals, by name: a device is listed only once it was polled.
    std::map<std::string, std::chrono::milliseconds> intervals;
    std::vector<std::shared_ptr<ValueSubscriber>> subscribers;
};

}  // namespace detail

namespace {

using detail::DeviceEntry;
using detail::ValueHub;
using detail::ValueSubscriber;
using detail::SystemTime;

// Not `waiting`: the poller did not skip the device in back-off, so it learned something new.
bool polled(const device::WatchedDevice& state) { return device::polled(state.status); }

// Values were read: what can go stale.
bool answered(const device::WatchedDevice& state) { return device::answered(state.status); }

// When the device's last answered poll is overdue by more than the allowance; none when it
// cannot go stale (no interval declared, no answer to be stale).
std::optional<Instant> stale_from(const DeviceEntry& entry) {
    if (entry.latest.interval.count() <= 0 || !entry.answered_at) return std::nullopt;
    return *entry.answered_at + (1 + overdue_intervals_allowed) * entry.latest.interval;
}

bool overdue(const DeviceEntry& entry, Instant now) {
    const auto from = stale_from(entry);
    return from && now > *from;
}

std::string seconds_text(Instant::duration duration) {
    return fmt::format("{:.1f} s", std::chrono::duration<double>(duration).count());
}

std::string overdue_reason(const DeviceEntry& entry, Instant now) {
    return fmt::format("not polled for {} (polled every {}): its line is too busy to carry its polls, or a poll is "
                       "stuck; the last value read is no longer known to be the device's (the gateway's log and /metrics "
                       "say more)",
                       seconds_text(now - *entry.answered_at), seconds_text(entry.latest.interval));
}

// The device as its overdue poll leaves it: every value stale (the last one kept, with its
// age, for those who ask for the detail), the device stale.
device::WatchedDevice stale_state(const device::WatchedDevice& polled_state, const std::string& why) {
    device::WatchedDevice state = polled_state;
    state.status = device::DeviceStatus::stale;
    state.last_error = why;
    for (device::WatchedValue& value : state.values) {
        value.fresh = false;
        value.changed = false;
        value.error = why;
    }
    return state;
}

CachedDevice as_seen(const DeviceEntry& entry, Instant now) {
    CachedDevice device = entry.latest;
    device.seen_at = now;
    if (entry.answered_at) {
        device.since_answered = std::chrono::duration_cast<std::chrono::milliseconds>(now - *entry.answered_at);
    }
    if (overdue(entry, now)) device.state = stale_state(device.state, overdue_reason(entry, now));
    return device;
}

ValueChange device_change(const std::string& name, const device::WatchedDevice& state, SystemTime sampled) {
    ValueChange change;
    change.device = name;
    change.device_status = state.status;
    change.status = device::status_text(state.status);
    if (state.status != device::DeviceStatus::ok) change.error = state.last_error;
    change.sampled = sampled;
    return change;
}

ValueChange value_change(const std::string& name, const device::WatchedDevice& state, const device::WatchedValue& value,
                         SystemTime sampled) {
    const device::Parameter& parameter = *value.parameter;
    ValueChange change;
    change.device = name;
    change.parameter = parameter.name;
    // The view the command line, the library and the HTTP API show (client/resolved_value.hpp):
    // the unit as the device is configured, its limits as it holds them, the text.
    const auto resolved = device::resolve_value(parameter, value.last ? &*value.last : nullptr, state.known);
    change.unit = resolved.unit;
    change.decimals = resolved.decimals;
    change.limits = resolved.limits;
    change.status = device::value_status(state, value);
    change.sampled = sampled;
    if (value.fresh) {
        change.value = value.last;
        change.text = resolved.text;
    } else {
        change.error = value.error;
    }
    return change;
}

// The device's status, then each parameter: what a subscriber is told, before comparing.
std::vector<ValueChange> state_of(const std::string& name, const device::WatchedDevice& state, SystemTime sampled) {
    std::vector<ValueChange> changes{device_change(name, state, sampled)};
    for (const device::WatchedValue& value : state.values) changes.push_back(value_change(name, state, value, sampled));
    return changes;
}

bool same_value(const std::optional<device::EngineeringValue>& a, const std::optional<device::EngineeringValue>& b) {
    if (a.has_value() != b.has_value()) return false;
    return !a || (a->raw == b->raw && a->status == b->status && a->value == b->value && a->unit == b->unit &&
                  a->decimals == b->decimals);
}

// A new error message with the same status is not a change: the status says what matters.
bool same_state(const ValueChange& a, const ValueChange& b) {
    return a.parameter == b.parameter && a.status == b.status && same_value(a.value, b.value) && a.limits == b.limits;
}

// What differs between what was last told and `now` (all of it when the parameters are not the
// same ones); `now` becomes what was last told.
std::vector<ValueChange> publish(std::vector<ValueChange>& told, std::vector<ValueChange> now) {
    std::vector<ValueChange> changes;
    const bool comparable = told.size() == now.size();
    for (std::size_t i = 0; i < now.size(); ++i) {
        if (!comparable || !same_state(told[i], now[i])) changes.push_back(now[i]);
    }
    told = std::move(now);
    return changes;
}

DeviceEntry& entry_of(ValueHub& hub, const std::string& name) {
    auto it = std::find_if(hub.devices.begin(), hub.devices.end(),
                           [&](const DeviceEntry& entry) { return entry.latest.name == name; });
    if (it != hub.devices.end()) return *it;
    const auto interval = hub.intervals.find(name);
    CachedDevice device{name, {}, {}, interval != hub.intervals.end() ? interval->second : std::chrono::milliseconds(0), {}};
    hub.devices.push_back({std::move(device), {}, {}, {}, false});
    return hub.devices.back();
}

// The stamp a device's next changes are told with: `time`, unless that is not later than the
// last changes told of it (the same millisecond as a `stale`, a wall clock set back); then 1 ms
// after those, so that the device's changes keep the order they happened in by their stamps.
SystemTime next_stamp(DeviceEntry& entry, SystemTime time) {
    if (entry.told_at && time <= *entry.told_at) time = *entry.told_at + std::chrono::milliseconds(1);
    entry.told_at = time;
    return time;
}

// With the subscriber's mutex held. Checked before each call: the callback may end its own
// subscription.
void call(ValueSubscriber& subscriber, const std::vector<ValueChange>& changes) {
    for (const ValueChange& change : changes) {
        if (!subscriber.active) return;
        subscriber.callback(change);
    }
}

void deliver(ValueSubscriber& subscriber, const std::vector<ValueChange>& changes) {
    std::lock_guard lock(subscriber.mutex);
    call(subscriber, changes);
}

void remove(ValueHub& hub, const std::shared_ptr<ValueSubscriber>& subscriber) {
    std::lock_guard lock(hub.mutex);
    std::erase(hub.subscribers, subscriber);
}

}  // namespace

// ---------------------------------------------------------------------------------------------

ValueSubscription::ValueSubscription(std::weak_ptr<detail::ValueHub> hub,
                                     std::shared_ptr<detail::ValueSubscriber> subscriber)
    : hub_(std::move(hub)), subscriber_(std::move(subscriber)) {}

ValueSubscription::~ValueSubscription() { reset(); }

ValueSubscription& ValueSubscription::operator=(ValueSubscription&& other) noexcept {
    if (this == &other) return *this;
    reset();
    hub_ = std::move(other.hub_);
    subscriber_ = std::move(other.subscriber_);
    return *this;
}

void ValueSubscription::reset() {
    if (!subscriber_) return;
    {
        // Waits for a callback running on another thread; none starts after this.
        std::lock_guard lock(subscriber_->mutex);
        subscriber_->active = false;
    }
    if (auto hub = hub_.lock()) remove(*hub, subscriber_);
    subscriber_.reset();
    hub_.reset();
}

// ---------------------------------------------------------------------------------------------

ValueCache::ValueCache(std::shared_ptr<Clock> clock, WallClock wall)
    : hub_(std::make_shared<ValueHub>(std::move(clock), std::move(wall))) {}
ValueCache::~ValueCache() = default;

void ValueCache::expect_polls(const std::string& name, std::chrono::milliseconds interval) {
    std::lock_guard lock(hub_->mutex);
    hub_->intervals[name] = interval;
    for (DeviceEntry& entry : hub_->devices) {
        if (entry.latest.name == name) entry.latest.interval = interval;
    }
}

void ValueCache::update(const std::string& name, const device::WatchedDevice& state, SystemTime sampled) {
    std::lock_guard telling(hub_->telling);
    std::vector<ValueChange> changes;
    std::vector<std::shared_ptr<ValueSubscriber>> subscribers;
    {
        std::lock_guard lock(hub_->mutex);
        DeviceEntry& entry = entry_of(*hub_, name);
        // Skipped in back-off, the device is still what its last poll found (no-reply,
        // line-down): so say the API, /metrics and the dashboard, as MQTT does, not "waiting".
        if (!polled(state) && polled(entry.latest.state)) return;
        entry.latest.state = state;
        entry.latest.sampled = sampled;
        if (!polled(state)) return;
        if (answered(state)) {
            entry.answered_at = hub_->clock->now();
        } else {
            entry.answered_at.reset();
        }
        entry.told_stale = false;
        changes = publish(entry.published, state_of(name, state, next_stamp(entry, sampled)));
        if (changes.empty()) return;
        subscribers = hub_->subscribers;
    }
    // Outside the hub's lock: the other groups' snapshots do not wait for callbacks.
    for (const auto& subscriber : subscribers) deliver(*subscriber, changes);
}

std::vector<std::string> ValueCache::mark_overdue() {
    std::lock_guard telling(hub_->telling);
    std::vector<std::string> stale;
    std::vector<ValueChange> changes;
    std::vector<std::shared_ptr<ValueSubscriber>> subscribers;
    {
        std::lock_guard lock(hub_->mutex);
        const Instant now = hub_->clock->now();
        for (DeviceEntry& entry : hub_->devices) {
            if (!overdue(entry, now)) continue;
            const std::string& name = entry.latest.name;
            stale.push_back(name);
            if (std::exchange(entry.told_stale, true)) continue;
            // Stamped now, when it is told, not when it became stale (up to a timer tick
            // earlier): a history heartbeat of the value written meanwhile then never lies after
            // the row that says it is stale.
            auto told = publish(entry.published, state_of(name, stale_state(entry.latest.state, overdue_reason(entry, now)),
                                                          next_stamp(entry, hub_->wall())));
            changes.insert(changes.end(), told.begin(), told.end());
        }
        if (changes.empty()) return stale;
        subscribers = hub_->subscribers;
    }
    for (const auto& subscriber : subscribers) deliver(*subscriber, changes);
    return stale;
}

std::vector<CachedDevice> ValueCache::snapshot() const {
    std::lock_guard lock(hub_->mutex);
    const Instant now = hub_->clock->now();
    std::vector<CachedDevice> devices;
    devices.reserve(hub_->devices.size());
    for (const DeviceEntry& entry : hub_->devices) devices.push_back(as_seen(entry, now));
    return devices;
}

std::vector<ValueChange> ValueCache::told(const std::string& name) const {
    std::lock_guard lock(hub_->mutex);
    const auto it = std::find_if(hub_->devices.begin(), hub_->devices.end(),
                                 [&](const DeviceEntry& entry) { return entry.latest.name == name; });
    return it == hub_->devices.end() ? std::vector<ValueChange>{} : it->published;
}

DeviceLookup ValueCache::device_lookup() const {
    return [hub = std::weak_ptr<ValueHub>(hub_)](const std::string& name) -> std::optional<DeviceSeen> {
        const auto held = hub.lock();
        if (!held) return std::nullopt;
        std::lock_guard lock(held->mutex);
        for (const DeviceEntry& entry : held->devices) {
            if (entry.latest.name != name) continue;
            const Instant now = held->clock->now();
            if (overdue(entry, now)) return DeviceSeen{device::DeviceStatus::stale, overdue_reason(entry, now)};
            return DeviceSeen{entry.latest.state.status, entry.latest.state.last_error};
        }
        return std::nullopt;
    };
}

ValueSubscription ValueCache::subscribe(ValueCallback callback) {
    auto subscriber = std::make_shared<ValueSubscriber>(std::move(callback));
    // Held from before it is listed until the picture is told: a change found meanwhile is
    // delivered after the picture, never before it.
    std::unique_lock telling(subscriber->mutex);
    std::vector<ValueChange> picture;
    {
        std::lock_guard lock(hub_->mutex);
        for (const DeviceEntry& entry : hub_->devices) {
            picture.insert(picture.end(), entry.published.begin(), entry.published.end());
        }
        hub_->subscribers.push_back(subscriber);
    }
    ValueSubscription subscription(hub_, subscriber);
    call(*subscriber, picture);
    return subscription;
}

}  // namespace loopwire::gateway
