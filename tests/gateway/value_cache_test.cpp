// The value cache and its change stream (gateway/value_cache.hpp): what a subscriber is told
// for each sample, when it stops being told, and updates from several poll-group threads while
// subscriptions come and go.
#include <gtest/gtest.h>

#include <atomic>
#include <map>
#include <mutex>
#include <thread>

#include "gateway/value_cache.hpp"
#include "common/never_sent.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;

const auto sample_time = std::chrono::system_clock::time_point{} + 1000h;

// Wall time for the stale changes' stamps: moves only when the test moves it.
class SystemTimeForTests {
public:
    explicit SystemTimeForTests(std::chrono::system_clock::time_point start) : now_(std::make_shared<std::atomic<std::int64_t>>(ms(start))) {}
    void advance(std::chrono::milliseconds length) { now_->fetch_add(length.count()); }
    ValueCache::WallClock clock() const {
        return [now = now_] { return std::chrono::system_clock::time_point(std::chrono::milliseconds(now->load())); };
    }

private:
    static std::int64_t ms(std::chrono::system_clock::time_point time) {
        return std::chrono::duration_cast<std::chrono::milliseconds>(time.time_since_epoch()).count();
    }
    std::shared_ptr<std::atomic<std::int64_t>> now_;
};

device::Parameter parameter(std::string name, std::string unit) {
    device::Parameter p;
    p.name = std::move(name);
    p.type = device::ValueType::int16;
    p.decimals = 1;
    p.unit = std::move(unit);
    return p;
}

device::EngineeringValue tenths(std::uint16_t raw, std::string status = "ok") {
    return {static_cast<double>(raw) / 10.0, std::move(status), raw, "°C"};
}

// A device watched for two parameters, its state folded from polls as the poller does.
class Device {
public:
    Device() : state_(device::watch("tc10@3", {&measured_, &set_point_})) {}
    Device(const Device&) = delete;
    Device& operator=(const Device&) = delete;

    const device::WatchedDevice& answered(std::optional<device::EngineeringValue> measured,
                                          device::EngineeringValue set_point) {
        device::ReadReport report;
        report.readings.push_back({&measured_, measured, measured ? "" : "exception 2 (illegal data address)"});
        report.readings.push_back({&set_point_, set_point, ""});
        device::record_poll(state_, report, true, "", device::MonitorClock::now());
        return state_;
    }
    const device::WatchedDevice& silent() {
        device::record_poll(state_, {}, false, "timeout: no reply from unit 3", device::MonitorClock::now());
        return state_;
    }
    const device::WatchedDevice& backing_off() {
        device::record_skipped(state_);
        return state_;
    }
    // The poll's first block was read, its second ended with `why`, which tells nothing of the
    // device (common/never_sent.hpp): it expired in the line's queue, or the line was closed.
    const device::WatchedDevice& unsent(device::EngineeringValue measured, const Error& why) {
        device::ReadReport report;
        report.readings.push_back({&measured_, measured, ""});
        report.readings.push_back({&set_point_, std::nullopt, why.message});
        device::record_outcome(state_, report, why, device::MonitorClock::now());
        return state_;
    }

private:
    device::Parameter measured_ = parameter("measured_value", "°C");
    device::Parameter set_point_ = parameter("set_point", "°C");
    device::WatchedDevice state_;
};

// Everything a subscriber was told, in order.
struct Told {
    std::vector<ValueChange> changes;
    ValueCallback collect() {
        return [this](const ValueChange& change) { changes.push_back(change); };
    }
    std::vector<std::string> names() const {
        std::vector<std::string> names;
        for (const auto& change : changes) {
            names.push_back(change.about_device() ? "(" + change.status + ")" : change.parameter);
        }
        return names;
    }
};

TEST(ValueCache, TheFirstSampleTellsTheDevicesStatusAndEveryParameter) {
    ValueCache cache;
    Told told;
    auto subscription = cache.subscribe(told.collect());
    Device oven;
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    ASSERT_EQ(told.names(), (std::vector<std::string>{"(ok)", "measured_value", "set_point"}));
    const ValueChange& device = told.changes[0];
    EXPECT_EQ(device.device, "oven1");
    EXPECT_TRUE(device.about_device());
    EXPECT_FALSE(device.value.has_value());
    EXPECT_EQ(device.sampled, sample_time);
    const ValueChange& set_point = told.changes[2];
    EXPECT_EQ(set_point.device, "oven1");
    ASSERT_TRUE(set_point.value.has_value());
    EXPECT_EQ(std::get<double>(set_point.value->value), 137.5);
    EXPECT_EQ(set_point.value->raw, 1375);
    EXPECT_EQ(set_point.text, "137.5");
    EXPECT_EQ(set_point.unit, "°C");
    EXPECT_EQ(set_point.status, "ok");
    EXPECT_EQ(set_point.error, "");
    EXPECT_EQ(set_point.sampled, sample_time);
}

// A value is told with the view every front resolves (client/resolved_value.hpp): a set point
// not read yet has the unit its configuration word says and the limits its bounding words set,
// as the HTTP API and the command line show them, not the profile's default.
TEST(ValueCache, AValueNotReadYetHasItsConfiguredUnitAndLimits) {
    const auto tc10 = device::testing::builtin("tc10");
    ASSERT_TRUE(tc10);
    const device::Parameter& sp = device::testing::parameter(*tc10, "set_point");
    device::WatchedDevice state = device::watch("tc10@3", {&sp});
    state.status = device::DeviceStatus::no_reply;
    state.known = {{"temperature_unit", 1}, {"decimal_point", 0}, {"set_point_low_limit", 10}, {"set_point_high_limit", 500}};
    ValueCache cache;
    Told told;
    auto subscription = cache.subscribe(told.collect());
    cache.update("oven1", state, sample_time);
    ASSERT_EQ(told.changes.size(), 2u);
    const ValueChange& change = told.changes[1];
    EXPECT_FALSE(change.value.has_value());
    EXPECT_EQ(change.unit, "°F");
    EXPECT_EQ(change.limits, (device::ValueLimits{10.0, 500.0}));
}

TEST(ValueCache, AnUnchangedSampleTellsNothing) {
    ValueCache cache;
    Told told;
    auto subscription = cache.subscribe(told.collect());
    Device oven;
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time + 1s);
    EXPECT_EQ(told.changes.size(), 3u);
}

TEST(ValueCache, AChangedValueTellsExactlyThatOne) {
    ValueCache cache;
    Told told;
    auto subscription = cache.subscribe(told.collect());
    Device oven;
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    told.changes.clear();
    cache.update("oven1", oven.answered(tenths(251), tenths(1375)), sample_time + 1s);
    ASSERT_EQ(told.names(), std::vector<std::string>{"measured_value"});
    EXPECT_EQ(told.changes[0].text, "25.1");
    EXPECT_EQ(told.changes[0].sampled, sample_time + 1s);
}

TEST(ValueCache, AValuesStatusChangeTellsOne) {
    ValueCache cache;
    Told told;
    auto subscription = cache.subscribe(told.collect());
    Device oven;
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    told.changes.clear();
    // The same word, now read as a special state: the status is what changed.
    cache.update("oven1", oven.answered(device::EngineeringValue{std::monostate{}, "under-range", 250, ""}, tenths(1375)),
                 sample_time + 1s);
    ASSERT_EQ(told.names(), std::vector<std::string>{"measured_value"});
    EXPECT_EQ(told.changes[0].status, "under-range");
}

TEST(ValueCache, AValueThatFailsTellsItsErrorAndTheDevicesPartialStatus) {
    ValueCache cache;
    Told told;
    auto subscription = cache.subscribe(told.collect());
    Device oven;
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    told.changes.clear();
    cache.update("oven1", oven.answered(std::nullopt, tenths(1375)), sample_time + 1s);
    ASSERT_EQ(told.names(), (std::vector<std::string>{"(partial)", "measured_value"}));
    EXPECT_EQ(told.changes[1].status, "error");
    EXPECT_FALSE(told.changes[1].value.has_value());
    EXPECT_EQ(told.changes[1].text, "");
    EXPECT_EQ(told.changes[1].error, "exception 2 (illegal data address)");
}

TEST(ValueCache, ADeviceThatStopsAnsweringTellsItsStatusAndEachValues) {
    ValueCache cache;
    Told told;
    auto subscription = cache.subscribe(told.collect());
    Device oven;
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    told.changes.clear();
    cache.update("oven1", oven.silent(), sample_time + 1s);
    ASSERT_EQ(told.names(), (std::vector<std::string>{"(no-reply)", "measured_value", "set_point"}));
    EXPECT_EQ(told.changes[0].error, "timeout: no reply from unit 3");
    EXPECT_EQ(told.changes[1].status, "no-reply");
    EXPECT_FALSE(told.changes[1].value.has_value());
}

// A device in back-off is not polled: the poller says "waiting", which is no news.
TEST(ValueCache, ASampleThatSkipsADeviceInBackOffTellsNothing) {
    ValueCache cache;
    Told told;
    auto subscription = cache.subscribe(told.collect());
    Device oven;
    cache.update("oven1", oven.silent(), sample_time);
    told.changes.clear();
    cache.update("oven1", oven.backing_off(), sample_time + 1s);
    EXPECT_TRUE(told.changes.empty()) << told.names().size();
    // Skipped in back-off it is still what its last poll found, on every front: subscribers were
    // told no-reply, and so says the snapshot (the API, /metrics), not "waiting".
    EXPECT_EQ(cache.snapshot().at(0).state.status, device::DeviceStatus::no_reply);
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time + 2s);
    EXPECT_EQ(told.names(), (std::vector<std::string>{"(ok)", "measured_value", "set_point"}));
}

// A poll the line never sent (busy with writes and clients until the poll's deadline), or whose
// line was closed under it (a gateway stopping or reloading, Master::close), is no news of the
// device: it stays what its last poll found, with its values, on every front; it does not become
// `no-reply`, `line-down`, a `partial` read or an offline device (the Sparkplug node's DDEATH).
TEST(ValueCache, APollThatWasNeverSentOrAbandonedTellsNothing) {
    const Error never_sent = make_error(ErrorKind::timeout, "unit 3: the deadline passed before the line was free; not sent", not_sent_code);
    const Error abandoned = make_error(ErrorKind::link, "line kiln (rtu:/dev/ttyUSB0) is closing", abandoned_code);
    for (const Error& why : {never_sent, abandoned}) {
        SCOPED_TRACE(why.message);
        ValueCache cache;
        Told told;
        auto subscription = cache.subscribe(told.collect());
        Device oven;
        cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
        told.changes.clear();
        const auto& state = oven.unsent(tenths(251), why);
        EXPECT_EQ(state.status, device::DeviceStatus::waiting);
        EXPECT_EQ(state.errors, 0U) << "not a failed poll";
        EXPECT_EQ(state.last_error, why.message) << "the sample says why";
        cache.update("oven1", state, sample_time + 1s);
        EXPECT_TRUE(told.changes.empty()) << told.names().size();
        const auto seen = cache.snapshot().at(0);
        EXPECT_EQ(seen.state.status, device::DeviceStatus::ok);
        EXPECT_EQ(seen.state.values.at(1).last->raw, 1375);
        EXPECT_TRUE(seen.state.values.at(1).fresh);
        cache.update("oven1", oven.answered(tenths(252), tenths(2100)), sample_time + 2s);
        EXPECT_EQ(told.names(), (std::vector<std::string>{"measured_value", "set_point"}));
    }
}

// Staleness, in virtual time: a device polled every second whose poll stops coming back.
class ValueCacheStaleness : public ::testing::Test {
protected:
    void SetUp() override { cache.expect_polls("oven1", 1s); }

    std::shared_ptr<VirtualClock> clock = std::make_shared<VirtualClock>();
    SystemTimeForTests wall{sample_time};
    ValueCache cache{clock, wall.clock()};
    Device oven;
    Told told;
    ValueSubscription subscription = cache.subscribe(told.collect());
};

TEST_F(ValueCacheStaleness, APollMoreThanTwoIntervalsOverdueMakesTheDeviceAndItsValuesStale) {
    cache.update("oven1", oven.answered(tenths(3550), tenths(1375)), sample_time);
    told.changes.clear();

    // Due after 1 s, overdue by exactly two intervals at 3 s: still current.
    clock->advance(3s);
    wall.advance(3s);
    EXPECT_TRUE(cache.mark_overdue().empty());
    EXPECT_EQ(cache.snapshot().at(0).state.status, device::DeviceStatus::ok);
    EXPECT_EQ(cache.snapshot().at(0).since_answered, 3s);
    EXPECT_TRUE(told.changes.empty());

    clock->advance(1ms);
    wall.advance(1ms);
    // Read from the clock at once, before any timer has told the subscribers.
    const auto seen = cache.snapshot().at(0);
    EXPECT_EQ(seen.state.status, device::DeviceStatus::stale);
    EXPECT_NE(seen.state.last_error.find("not polled for 3.0 s (polled every 1.0 s)"), std::string::npos) << seen.state.last_error;
    const auto& measured = seen.state.values.at(0);
    EXPECT_EQ(device::value_status(seen.state, measured), "stale");
    EXPECT_FALSE(measured.fresh);
    ASSERT_TRUE(measured.last) << "the last value is kept for those who ask how old it is";
    EXPECT_EQ(measured.last->raw, 3550);
    EXPECT_TRUE(told.changes.empty());

    EXPECT_EQ(cache.mark_overdue(), (std::vector<std::string>{"oven1"}));
    ASSERT_EQ(told.names(), (std::vector<std::string>{"(stale)", "measured_value", "set_point"}));
    for (const auto& change : told.changes) {
        EXPECT_EQ(change.status, "stale") << change.parameter;
        EXPECT_FALSE(change.value) << change.parameter << ": a stale change carries no value";
        EXPECT_EQ(change.text, "") << change.parameter;
        EXPECT_NE(change.error.find("not polled for"), std::string::npos) << change.parameter;
        EXPECT_EQ(change.sampled, sample_time + 3001ms) << "stamped when it was found stale";
    }
    told.changes.clear();
    clock->advance(10s);
    EXPECT_EQ(cache.mark_overdue(), (std::vector<std::string>{"oven1"})) << "still stale";
    EXPECT_TRUE(told.changes.empty()) << "told once";
}

TEST_F(ValueCacheStaleness, TheNextPollMakesItOkAgain) {
    cache.update("oven1", oven.answered(tenths(3550), tenths(1375)), sample_time);
    clock->advance(5s);
    (void)cache.mark_overdue();
    told.changes.clear();

    cache.update("oven1", oven.answered(tenths(3971), tenths(1375)), sample_time + 5s);
    ASSERT_EQ(told.names(), (std::vector<std::string>{"(ok)", "measured_value", "set_point"}));
    EXPECT_EQ(told.changes[1].text, "397.1");
    EXPECT_EQ(told.changes[2].text, "137.5") << "an unchanged value is told again: it was stale";
    EXPECT_EQ(cache.snapshot().at(0).state.status, device::DeviceStatus::ok);
    EXPECT_TRUE(cache.mark_overdue().empty());
}

// A reply stamped no later than the `stale` it ends (the same millisecond, a reply time from
// before it, a wall clock set back) is told 1 ms after it: whoever files a device's changes by
// their stamps (the history) has them in the order they happened.
TEST_F(ValueCacheStaleness, ADevicesChangesAreStampedInTheOrderTheyAreTold) {
    cache.update("oven1", oven.answered(tenths(3550), tenths(1375)), sample_time);
    clock->advance(5s);
    wall.advance(5s);
    (void)cache.mark_overdue();
    ASSERT_FALSE(told.changes.empty());
    const auto stale_at = told.changes.back().sampled;
    EXPECT_EQ(stale_at, sample_time + 5s);
    told.changes.clear();

    cache.update("oven1", oven.answered(tenths(3971), tenths(1375)), sample_time + 5s);  // the same millisecond
    ASSERT_EQ(told.names(), (std::vector<std::string>{"(ok)", "measured_value", "set_point"}));
    for (const auto& change : told.changes) EXPECT_EQ(change.sampled, stale_at + 1ms);
    told.changes.clear();
    cache.update("oven1", oven.answered(tenths(3972), tenths(1375)), sample_time + 1s);  // earlier still
    ASSERT_EQ(told.names(), (std::vector<std::string>{"measured_value"}));
    EXPECT_EQ(told.changes[0].sampled, stale_at + 2ms);
    told.changes.clear();
    cache.update("oven1", oven.answered(tenths(3973), tenths(1375)), sample_time + 6s);  // later: as it is
    ASSERT_EQ(told.names(), (std::vector<std::string>{"measured_value"}));
    EXPECT_EQ(told.changes[0].sampled, sample_time + 6s);
}

// A device whose polls get no answer shows no value that could be stale: it stays no-reply,
// however long its back-off; and a device never declared never goes stale.
TEST_F(ValueCacheStaleness, NoReplyAndUndeclaredDevicesDoNotGoStale) {
    Device kiln;
    cache.update("oven1", oven.silent(), sample_time);
    cache.update("kiln", kiln.answered(tenths(250), tenths(1375)), sample_time);
    clock->advance(1h);
    cache.update("oven1", oven.backing_off(), sample_time + 1h);
    EXPECT_TRUE(cache.mark_overdue().empty());
    const auto devices = cache.snapshot();
    EXPECT_EQ(devices.at(0).state.status, device::DeviceStatus::no_reply);
    EXPECT_FALSE(devices.at(0).since_answered);
    EXPECT_EQ(devices.at(1).state.status, device::DeviceStatus::ok);
    EXPECT_EQ(devices.at(1).interval, 0ms);
}

// The staleness timer and a poll may find the same device at once: a subscriber still gets its
// changes in the order they were made, never a `stale` after the poll's `ok`.
TEST(ValueCacheStalenessThreads, AStaleFoundAsAPollArrivesNeverOvertakesIt) {
    auto clock = std::make_shared<VirtualClock>();
    ValueCache cache(clock);
    cache.expect_polls("oven1", 1ms);
    std::mutex mutex;
    std::vector<std::string> statuses;
    // A slow subscriber: while it takes one change, the timer's next and a poll's both wait
    // for it, which is where one could overtake the other.
    auto subscription = cache.subscribe([&](const ValueChange& change) {
        std::this_thread::sleep_for(100us);
        if (!change.about_device()) return;
        std::lock_guard lock(mutex);
        statuses.push_back(change.status);
    });
    std::atomic<bool> polling{true};
    std::atomic<unsigned> looks{0};
    std::thread timer([&] {
        while (polling.load()) {
            clock->advance(4ms);  // past the allowance at each look: stale unless a poll came
            (void)cache.mark_overdue();
            looks.fetch_add(1);
        }
    });
    Device oven;
    const auto told_count = [&] {
        std::lock_guard lock(mutex);
        return statuses.size();
    };
    // Until the two have met often enough (each stale and ok again is two), or a generous limit.
    const auto give_up = std::chrono::steady_clock::now() + 30s;
    while (told_count() < 400 && std::chrono::steady_clock::now() < give_up) {
        // Each poll waits for the timer to have looked once more, so the two keep meeting;
        // the timer's next look then runs while this poll does.
        const unsigned looked = looks.load();
        cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
        while (looks.load() == looked && std::chrono::steady_clock::now() < give_up) std::this_thread::yield();
    }
    polling.store(false);
    timer.join();
    // Out of order, a subscriber would hear "ok" twice in a row (the poll's, then the one
    // before the overtaken "stale") and end on a status the cache no longer has.
    std::lock_guard lock(mutex);
    ASSERT_GE(statuses.size(), 400u) << "the timer and the polls met too seldom in 30 s";
    for (std::size_t i = 1; i < statuses.size(); ++i) {
        ASSERT_NE(statuses[i], statuses[i - 1]) << "told " << statuses[i] << " twice in a row at " << i;
    }
    EXPECT_EQ(statuses.back(), device::status_text(cache.snapshot().at(0).state.status));
}

TEST(ValueCache, ALateSubscriberIsToldTheWholePictureFirst) {
    ValueCache cache;
    Device oven;
    Device kiln;
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    cache.update("kiln", kiln.silent(), sample_time);
    cache.update("oven1", oven.answered(tenths(251), tenths(1375)), sample_time + 1s);
    Told told;
    auto subscription = cache.subscribe(told.collect());
    ASSERT_EQ(told.names(), (std::vector<std::string>{"(ok)", "measured_value", "set_point", "(no-reply)",
                                                      "measured_value", "set_point"}));
    EXPECT_EQ(told.changes[1].text, "25.1");
    EXPECT_EQ(told.changes[1].sampled, sample_time + 1s);
    EXPECT_EQ(told.changes[3].device, "kiln");
}

TEST(ValueCache, TheSnapshotHoldsTheLastSampleOfEachDeviceInTheOrderFirstSeen) {
    ValueCache cache;
    Device oven;
    Device kiln;
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    cache.update("kiln", kiln.silent(), sample_time);
    cache.update("oven1", oven.answered(tenths(251), tenths(1375)), sample_time + 1s);
    const auto devices = cache.snapshot();
    ASSERT_EQ(devices.size(), 2u);
    EXPECT_EQ(devices[0].name, "oven1");
    EXPECT_EQ(devices[0].sampled, sample_time + 1s);
    EXPECT_EQ(devices[0].state.values.at(0).last->raw, 251);
    EXPECT_EQ(devices[1].name, "kiln");
    EXPECT_EQ(devices[1].state.status, device::DeviceStatus::no_reply);
}

TEST(ValueCache, AnEndedSubscriptionIsToldNothingMore) {
    ValueCache cache;
    Device oven;
    Told kept;
    Told ended;
    auto keeping = cache.subscribe(kept.collect());
    {
        auto subscription = cache.subscribe(ended.collect());
        EXPECT_TRUE(subscription.active());
    }
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    EXPECT_EQ(kept.changes.size(), 3u);
    EXPECT_TRUE(ended.changes.empty());

    keeping.reset();
    EXPECT_FALSE(keeping.active());
    cache.update("oven1", oven.answered(tenths(251), tenths(1375)), sample_time + 1s);
    EXPECT_EQ(kept.changes.size(), 3u);
}

TEST(ValueCache, AssigningASubscriptionEndsTheOneItHeld) {
    ValueCache cache;
    Device oven;
    Told first;
    Told second;
    auto subscription = cache.subscribe(first.collect());
    subscription = cache.subscribe(second.collect());
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    EXPECT_TRUE(first.changes.empty());
    EXPECT_EQ(second.changes.size(), 3u);
}

TEST(ValueCache, ASubscriptionMayOutliveTheCache) {
    ValueSubscription subscription;
    {
        ValueCache cache;
        subscription = cache.subscribe([](const ValueChange&) {});
    }
    subscription.reset();
    EXPECT_FALSE(subscription.active());
}

TEST(ValueCache, ACallbackMayEndItsOwnSubscriptionAndReadTheSnapshot) {
    ValueCache cache;
    Device oven;
    ValueSubscription subscription;
    std::vector<std::size_t> seen;
    subscription = cache.subscribe([&](const ValueChange&) {
        seen.push_back(cache.snapshot().size());
        subscription.reset();
    });
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time);
    EXPECT_EQ(seen, std::vector<std::size_t>{1}) << "called again after it ended its subscription";
}

// Two poll groups update their devices while subscriptions come and go on a third thread. A
// callback must never run after its subscription ended, nor twice at once; each device's
// values arrive in the order they were sampled. Run it under ThreadSanitizer too.
TEST(ValueCache, UpdatesFromTwoThreadsWhileSubscriptionsComeAndGo) {
    ValueCache cache;
    constexpr int subscriptions = 300;
    constexpr int most_samples = 60000;  // below 65536: the raw words only grow
    std::atomic<bool> subscribing{true};
    std::atomic<int> polling{0};  // poll groups that have sampled once
    auto poll_group = [&](const std::string& name, int& last) {
        Device device;
        for (int i = 0; i < most_samples && (i < 1000 || subscribing); ++i) {
            cache.update(name, device.answered(tenths(static_cast<std::uint16_t>(i)), tenths(1375)),
                         sample_time + i * 1ms);
            last = i;
            if (i == 0) ++polling;
        }
    };

    std::atomic<int> calls{0};
    std::atomic<int> late_calls{0};
    std::atomic<int> overlapping_calls{0};
    std::atomic<int> out_of_order{0};
    std::thread subscriber([&] {
        while (polling < 2) std::this_thread::yield();  // else every round may be over before the first sample
        for (int round = 0; round < subscriptions; ++round) {
            std::atomic<bool> ended{false};
            std::atomic<int> inside{0};
            std::map<std::string, int> last_raw;  // only touched by the callback, which never overlaps itself
            auto subscription = cache.subscribe([&](const ValueChange& change) {
                ++calls;
                if (inside.fetch_add(1) != 0) ++overlapping_calls;
                if (ended) ++late_calls;
                if (change.parameter == "measured_value") {
                    auto [it, fresh] = last_raw.try_emplace(change.device, change.value->raw);
                    if (!fresh && change.value->raw <= it->second) ++out_of_order;
                    it->second = change.value->raw;
                }
                inside.fetch_sub(1);
            });
            std::this_thread::yield();
            subscription.reset();
            ended = true;
        }
        subscribing = false;
    });
    int oven_last = -1;
    int kiln_last = -1;
    std::thread oven([&] { poll_group("oven1", oven_last); });
    std::thread kiln([&] { poll_group("kiln", kiln_last); });
    oven.join();
    kiln.join();
    subscriber.join();

    EXPECT_GT(calls.load(), 0);
    EXPECT_EQ(late_calls.load(), 0);
    EXPECT_EQ(overlapping_calls.load(), 0);
    EXPECT_EQ(out_of_order.load(), 0);
    const auto devices = cache.snapshot();
    ASSERT_EQ(devices.size(), 2u);
    EXPECT_EQ(devices[0].state.values.at(0).last->raw, devices[0].name == "oven1" ? oven_last : kiln_last);
    EXPECT_EQ(devices[1].state.values.at(0).last->raw, devices[1].name == "oven1" ? oven_last : kiln_last);
}

}  // namespace
}  // namespace loopwire::gateway
