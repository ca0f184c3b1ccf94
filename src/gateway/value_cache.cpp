#include "gateway/value_cache.hpp"

#include <algorithm>
#include <mutex>

#include "profile/value_format.hpp"

namespace loopwire::gateway {

// Locking: a subscriber's mutex is held while its callback runs; the hub's guards the devices
// and the list of subscribers and is never held while a callback runs. Where both are taken,
// the subscriber's comes first (a callback reading the snapshot; subscribe()), so they cannot
// deadlock.
namespace detail {

struct ValueSubscriber {
    explicit ValueSubscriber(ValueCallback f) : callback(std::move(f)) {}

    // Recursive: a callback may end its own subscription, which takes this mutex again.
    std::recursive_mutex mutex;
    bool active = true;
    ValueCallback callback;
};

struct DeviceEntry {
    CachedDevice latest;
    std::vector<ValueChange> published;  // the device's status, then each parameter, as last told
};

struct ValueHub {
    std::mutex mutex;
    std::vector<DeviceEntry> devices;  // in the order first seen
    std::vector<std::shared_ptr<ValueSubscriber>> subscribers;
};

}  // namespace detail

namespace {

using detail::DeviceEntry;
using detail::ValueHub;
using detail::ValueSubscriber;
using SystemTime = std::chrono::system_clock::time_point;

// "waiting": the poller skipped a device in back-off; it learned nothing new about it.
bool polled(const device::WatchedDevice& state) { return state.status != "waiting"; }

ValueChange device_change(const std::string& name, const device::WatchedDevice& state, SystemTime sampled) {
    ValueChange change;
    change.device = name;
    change.status = state.status;
    if (state.status != "ok") change.error = state.last_error;
    change.sampled = sampled;
    return change;
}

ValueChange value_change(const std::string& name, const device::WatchedDevice& state, const device::WatchedValue& value,
                         SystemTime sampled) {
    const device::Parameter& parameter = *value.parameter;
    ValueChange change;
    change.device = name;
    change.parameter = parameter.name;
    change.unit = device::shown_unit(parameter, value.last ? &*value.last : nullptr);  // as the device is configured
    change.status = device::value_status(state, value);
    change.sampled = sampled;
    if (value.fresh) {
        change.value = value.last;
        change.text = device::value_text(parameter, *value.last);
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
    return !a || (a->raw == b->raw && a->status == b->status && a->value == b->value && a->unit == b->unit);
}

// A new error message with the same status is not a change: the status says what matters.
bool same_state(const ValueChange& a, const ValueChange& b) {
    return a.parameter == b.parameter && a.status == b.status && same_value(a.value, b.value);
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
    hub.devices.push_back({CachedDevice{name, {}, {}}, {}});
    return hub.devices.back();
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

ValueCache::ValueCache() : hub_(std::make_shared<ValueHub>()) {}
ValueCache::~ValueCache() = default;

void ValueCache::update(const std::string& name, const device::WatchedDevice& state, SystemTime sampled) {
    std::vector<ValueChange> changes;
    std::vector<std::shared_ptr<ValueSubscriber>> subscribers;
    {
        std::lock_guard lock(hub_->mutex);
        DeviceEntry& entry = entry_of(*hub_, name);
        entry.latest.state = state;
        entry.latest.sampled = sampled;
        if (!polled(state)) return;
        changes = publish(entry.published, state_of(name, state, sampled));
        if (changes.empty()) return;
        subscribers = hub_->subscribers;
    }
    // Outside the hub's lock: the other groups' updates and snapshots do not wait for callbacks.
    for (const auto& subscriber : subscribers) deliver(*subscriber, changes);
}

std::vector<CachedDevice> ValueCache::snapshot() const {
    std::lock_guard lock(hub_->mutex);
    std::vector<CachedDevice> devices;
    devices.reserve(hub_->devices.size());
    for (const DeviceEntry& entry : hub_->devices) devices.push_back(entry.latest);
    return devices;
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
