// The poller (client/monitor_loop.hpp) against a scripted master: a poll that fails on the link
// shows the device "line-down", not "no-reply"; and with MonitorTarget::held_until (the
// gateway's line scheduler keeps the back-off) the poller skips the device only when told to
// and keeps no back-off of its own, so the two cannot compound.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <optional>
#include <stop_token>
#include <string>
#include <vector>

#include "client/monitor_loop.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using namespace std::chrono_literals;

// Fails every request with one error, counting them.
class FailingMaster final : public session::Master {
public:
    explicit FailingMaster(Error failure) : failure_(std::move(failure)) {}

    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override {
        ++requests;
        return failure_;
    }
    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override { done(execute(unit, request)); }
    Result<Bytes> forward(std::uint8_t, ByteView) override {
        ++requests;
        return failure_;
    }
    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override { done(forward(unit, pdu)); }
    std::string describe() const override { return "failing master"; }

    std::atomic<unsigned> requests{0};

private:
    Error failure_;
};

// Each sample's device state.
class Samples final : public SampleSink {
public:
    void write(const SampleView& sample) override {
        std::lock_guard lock(mutex_);
        states.push_back(sample.devices->at(0));
    }
    std::vector<WatchedDevice> states;

private:
    std::mutex mutex_;
};

MonitorTarget tc10_target(session::Master& master) {
    const auto& registry = testing::builtin_registry();
    auto address = parse_device_address(registry, "tc10@3");
    EXPECT_TRUE(address.ok());
    return MonitorTarget{&master, *address, {&testing::parameter(*address->profile, "set_point")}, {}};
}

std::vector<WatchedDevice> run(MonitorTarget target, unsigned samples) {
    MonitorSettings settings;
    settings.interval = 1ms;
    settings.count = samples;
    Samples sink;
    run_monitor({target}, settings, sink, std::stop_source().get_token());
    return sink.states;
}

TEST(MonitorLoop, APollThatFailsOnTheLinkIsLineDownNotNoReply) {
    FailingMaster master(make_error(ErrorKind::link, "line furnace (rtu:/dev/ttyUSB0) is down: no such port; retrying in 4 s"));
    auto target = tc10_target(master);
    target.held_until = [] { return std::optional<MonitorClock::time_point>(); };
    const auto states = run(target, 3);
    ASSERT_EQ(states.size(), 3u);
    for (const auto& state : states) {
        EXPECT_EQ(state.status, DeviceStatus::line_down);
        EXPECT_EQ(state.last_error, "line furnace (rtu:/dev/ttyUSB0) is down: no such port; retrying in 4 s");
        EXPECT_EQ(value_status(state, state.values.at(0)), "line-down");
        EXPECT_FALSE(state.next_try) << "the device backed off for its line";
    }
    EXPECT_EQ(master.requests, 3u) << "the device was not asked every sample";
}

TEST(MonitorLoop, WithHeldUntilASilentDeviceIsPolledWheneverTheCarrierSaysSo) {
    FailingMaster master(make_error(ErrorKind::timeout, "no reply from unit 3"));
    auto target = tc10_target(master);
    target.held_until = [] { return std::optional<MonitorClock::time_point>(); };
    const auto states = run(target, 4);
    ASSERT_EQ(states.size(), 4u);
    for (const auto& state : states) EXPECT_EQ(state.status, DeviceStatus::no_reply);
    EXPECT_EQ(master.requests, 4u) << "the poller backed off on its own as well";
}

TEST(MonitorLoop, WhileHeldTheDeviceIsSkippedAndTheTimeIsTheCarriers) {
    FailingMaster master(make_error(ErrorKind::timeout, "no reply from unit 3"));
    auto target = tc10_target(master);
    const auto until = MonitorClock::now() + 1h;
    target.held_until = [until] { return std::optional(until); };
    const auto states = run(target, 2);
    ASSERT_EQ(states.size(), 2u);
    for (const auto& state : states) {
        EXPECT_EQ(state.status, DeviceStatus::waiting);
        EXPECT_EQ(state.next_try, until);
    }
    EXPECT_EQ(master.requests, 0u);
}

}  // namespace
}  // namespace loopwire::device
