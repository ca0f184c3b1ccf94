// The value cache and its change stream (gateway/value_cache.hpp): what a subscriber is told
// for each sample, when it stops being told, and updates from several poll-group threads while
// subscriptions come and go.
#include <gtest/gtest.h>

#include <atomic>
#include <map>
#include <mutex>
#include <thread>

#include "gateway/value_cache.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;

const auto sample_time = std::chrono::system_clock::time_point{} + 1000h;

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
    EXPECT_EQ(cache.snapshot().at(0).state.status, "waiting") << "the snapshot is still the last sample";
    cache.update("oven1", oven.answered(tenths(250), tenths(1375)), sample_time + 2s);
    EXPECT_EQ(told.names(), (std::vector<std::string>{"(ok)", "measured_value", "set_point"}));
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
    EXPECT_EQ(devices[1].state.status, "no-reply");
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
