// The alarm engine on virtual time: no thread, no clock; each call is given its time.
#include <gtest/gtest.h>

#include "gateway/alarms/alarm_engine.hpp"

namespace loopwire::gateway::alarms {
namespace {

using namespace std::chrono_literals;

const Time t0 = Time(std::chrono::hours(24 * 365 * 50));

LimitAlarm high_limit(double limit, double deadband = 0, milliseconds on_delay = 0ms, milliseconds off_delay = 0ms) {
    LimitAlarm alarm;
    alarm.name = "temperature_high";
    alarm.device = "oven";
    alarm.parameter = "temperature";
    alarm.kind = LimitKind::high;
    alarm.limit = limit;
    alarm.deadband = deadband;
    alarm.on_delay = on_delay;
    alarm.off_delay = off_delay;
    alarm.severity = Severity::high;
    return alarm;
}

AlarmState state_of(const AlarmEngine& engine, const std::string& id) {
    for (const AlarmView& view : engine.views()) {
        if (view.id == id) return view.state;
    }
    ADD_FAILURE() << "no alarm " << id;
    return AlarmState::normal;
}

Transitions feed(AlarmEngine& engine, double value, Time now, std::string_view status = "ok") {
    return engine.feed("oven", "temperature", value, status, "°C", now);
}

TEST(AlarmEngine, AValueAboveTheLimitRaisesAnAlarmThatAnAcknowledgementAndAReturnTakeBackToNormal) {
    AlarmEngine engine({high_limit(250)}, {"oven"});
    EXPECT_TRUE(feed(engine, 240, t0).empty());
    const Transitions raised = feed(engine, 260, t0 + 1s);
    ASSERT_EQ(raised.size(), 1U);
    EXPECT_EQ(raised[0].id, "oven.temperature_high");
    EXPECT_EQ(raised[0].state, AlarmState::active_unacknowledged);
    EXPECT_EQ(raised[0].value, 260.0);
    EXPECT_EQ(raised[0].unit, "°C");
    EXPECT_EQ(raised[0].message, "temperature above 250");
    const auto acknowledged = engine.acknowledge("oven.temperature_high", "ann", "seen", t0 + 2s);
    ASSERT_TRUE(acknowledged.refusal.empty()) << acknowledged.refusal;
    ASSERT_EQ(acknowledged.transitions.size(), 1U);
    EXPECT_EQ(acknowledged.transitions[0].state, AlarmState::active_acknowledged);
    EXPECT_EQ(acknowledged.transitions[0].user, "ann");
    EXPECT_EQ(acknowledged.transitions[0].comment, "seen");
    const Transitions cleared = feed(engine, 240, t0 + 3s);
    ASSERT_EQ(cleared.size(), 1U);
    EXPECT_EQ(cleared[0].state, AlarmState::normal);
    EXPECT_FALSE(engine.acknowledge("oven.temperature_high", "ann", "", t0 + 4s).refusal.empty());
}

TEST(AlarmEngine, AnAlarmThatClearsBeforeItIsAcknowledgedIsReturnedUnacknowledgedUntilItIs) {
    AlarmEngine engine({high_limit(250)}, {});
    feed(engine, 260, t0);
    feed(engine, 240, t0 + 1s);
    EXPECT_EQ(state_of(engine, "oven.temperature_high"), AlarmState::returned_unacknowledged);
    const auto acknowledged = engine.acknowledge("oven.temperature_high", "ann", "", t0 + 2s);
    ASSERT_EQ(acknowledged.transitions.size(), 1U);
    EXPECT_EQ(acknowledged.transitions[0].state, AlarmState::normal);
}

// A PV wavering ±0.5 around the limit, fifty times: with a deadband of 1.0 one alarm, not fifty.
TEST(AlarmEngine, ADeadbandKeepsAValueWaveringAroundTheLimitToOneAlarm) {
    AlarmEngine with_deadband({high_limit(100, 1.0)}, {});
    AlarmEngine without({high_limit(100, 0.0)}, {});
    std::size_t raised_with = 0;
    std::size_t raised_without = 0;
    for (int i = 0; i < 100; ++i) {
        const double pv = i % 2 == 0 ? 100.5 : 99.5;
        for (const auto& transition : feed(with_deadband, pv, t0 + i * 1s)) {
            raised_with += transition.state == AlarmState::active_unacknowledged ? 1 : 0;
        }
        for (const auto& transition : feed(without, pv, t0 + i * 1s)) {
            raised_without += transition.state == AlarmState::active_unacknowledged ? 1 : 0;
        }
    }
    EXPECT_EQ(raised_with, 1U);
    EXPECT_EQ(raised_without, 50U);  // what the deadband spares the operator
    // Back past the limit by the deadband: it clears.
    feed(with_deadband, 98.9, t0 + 200s);
    EXPECT_EQ(state_of(with_deadband, "oven.temperature_high"), AlarmState::returned_unacknowledged);
}

TEST(AlarmEngine, AnOnDelayRaisesOnlyAConditionThatHeldForItAndTickRaisesItWithoutANewReading) {
    AlarmEngine engine({high_limit(250, 0, 10s, 5s)}, {});
    EXPECT_TRUE(feed(engine, 260, t0).empty());
    EXPECT_TRUE(engine.tick(t0 + 9s).empty());
    feed(engine, 240, t0 + 9500ms);  // back before the delay was over: nothing, and the delay starts again
    feed(engine, 261, t0 + 10s);
    EXPECT_TRUE(engine.tick(t0 + 19s).empty());
    const Transitions raised = engine.tick(t0 + 20s);
    ASSERT_EQ(raised.size(), 1U);
    EXPECT_EQ(raised[0].state, AlarmState::active_unacknowledged);
    EXPECT_EQ(raised[0].time, t0 + 20s);
    // The off delay: back below for less than 5 s changes nothing.
    feed(engine, 240, t0 + 21s);
    EXPECT_TRUE(engine.tick(t0 + 25s).empty());
    const Transitions cleared = engine.tick(t0 + 26s);
    ASSERT_EQ(cleared.size(), 1U);
    EXPECT_EQ(cleared[0].state, AlarmState::returned_unacknowledged);
}

TEST(AlarmEngine, AValueNotReadNeitherRaisesNorClears) {
    AlarmEngine engine({high_limit(250, 0, 5s)}, {});
    feed(engine, 260, t0);
    // Stale before the on delay is over: not raised, however long it stays stale.
    EXPECT_TRUE(engine.feed("oven", "temperature", std::nullopt, "stale", "°C", t0 + 1s).empty());
    EXPECT_TRUE(engine.tick(t0 + 60s).empty());
    EXPECT_EQ(state_of(engine, "oven.temperature_high"), AlarmState::normal);
    feed(engine, 260, t0 + 61s);
    ASSERT_EQ(engine.tick(t0 + 66s).size(), 1U);
    // Raised, then no reply and a failed read: it stays raised.
    EXPECT_TRUE(engine.feed("oven", "temperature", std::nullopt, "no-reply", "°C", t0 + 70s).empty());
    EXPECT_TRUE(engine.feed("oven", "temperature", 20.0, "error", "°C", t0 + 71s).empty());
    EXPECT_TRUE(engine.tick(t0 + 200s).empty());
    EXPECT_EQ(state_of(engine, "oven.temperature_high"), AlarmState::active_unacknowledged);
}

TEST(AlarmEngine, AShelvedAlarmIsQuietUntilItsShelvingEndsByItselfAndIsThenAnnouncedAgainIfStillActive) {
    AlarmEngine engine({high_limit(250)}, {});
    feed(engine, 260, t0);
    const auto shelved = engine.shelve("oven.temperature_high", 1h, "bob", "sensor being replaced", t0 + 1s);
    ASSERT_EQ(shelved.transitions.size(), 1U);
    EXPECT_EQ(shelved.transitions[0].state, AlarmState::shelved);
    EXPECT_EQ(shelved.transitions[0].shelved_until, t0 + 1s + 1h);
    // Whatever the value does while shelved, nobody is told.
    EXPECT_TRUE(feed(engine, 240, t0 + 10s).empty());
    EXPECT_TRUE(feed(engine, 270, t0 + 20s).empty());
    EXPECT_TRUE(engine.tick(t0 + 1h).empty());
    const Transitions ended = engine.tick(t0 + 1s + 1h);
    ASSERT_EQ(ended.size(), 1U);
    EXPECT_EQ(ended[0].state, AlarmState::active_unacknowledged);
    // Shelved while normal, it comes back normal.
    feed(engine, 240, t0 + 2h);
    engine.acknowledge("oven.temperature_high", "bob", "", t0 + 2h);
    engine.shelve("oven.temperature_high", 10min, "bob", "", t0 + 2h);
    const Transitions back = engine.tick(t0 + 2h + 10min);
    ASSERT_EQ(back.size(), 1U);
    EXPECT_EQ(back[0].state, AlarmState::normal);
}

TEST(AlarmEngine, OutOfServiceTellsNothingUntilReturnedToService) {
    AlarmEngine engine({high_limit(250)}, {});
    ASSERT_EQ(engine.remove_from_service("oven.temperature_high", "eve", "maintenance", t0).transitions.size(), 1U);
    EXPECT_TRUE(feed(engine, 260, t0 + 1s).empty());
    EXPECT_FALSE(engine.shelve("oven.temperature_high", 1h, "eve", "", t0 + 2s).refusal.empty());
    const auto back = engine.return_to_service("oven.temperature_high", "eve", "", t0 + 3s);
    ASSERT_EQ(back.transitions.size(), 1U);
    EXPECT_EQ(back.transitions[0].state, AlarmState::active_unacknowledged);
    EXPECT_TRUE(engine.acknowledge("nobody.nothing", "eve", "", t0).unknown);
}

TEST(AlarmEngine, ADeviationAlarmComparesThePvWithTheSetpoint) {
    LimitAlarm deviation = high_limit(5, 1);
    deviation.name = "temperature_deviation";
    deviation.kind = LimitKind::deviation;
    deviation.setpoint = "set_point";
    AlarmEngine engine({deviation}, {});
    EXPECT_TRUE(feed(engine, 300, t0).empty());  // no setpoint read yet: no verdict
    EXPECT_EQ(engine.feed("oven", "set_point", 200.0, "ok", "°C", t0 + 1s).size(), 1U);
    EXPECT_EQ(engine.feed("oven", "set_point", 295.5, "ok", "°C", t0 + 2s).size(), 0U);  // 4.5 off: within the deadband
    EXPECT_EQ(engine.feed("oven", "set_point", 296.5, "ok", "°C", t0 + 3s).size(), 1U);  // 3.5 off: back past it
    EXPECT_EQ(state_of(engine, "oven.temperature_deviation"), AlarmState::returned_unacknowledged);
}

TEST(AlarmEngine, ADeviceThatFallsSilentRaisesItsOwnAlarmAndALineDownRaisesTheLineOneInstead) {
    AlarmEngine engine({}, {"oven", "kiln"});
    const Transitions silent = engine.feed_device("oven", device::DeviceStatus::no_reply, t0);
    ASSERT_EQ(silent.size(), 1U);
    EXPECT_EQ(silent[0].id, "oven.silent");
    EXPECT_EQ(silent[0].state, AlarmState::active_unacknowledged);
    EXPECT_EQ(silent[0].severity, Severity::high);
    // Waiting in back-off says nothing new.
    EXPECT_TRUE(engine.feed_device("oven", device::DeviceStatus::waiting, t0 + 1s).empty());
    const Transitions line = engine.feed_device("oven", device::DeviceStatus::line_down, t0 + 2s);
    ASSERT_EQ(line.size(), 2U);
    EXPECT_EQ(state_of(engine, "oven.line_down"), AlarmState::active_unacknowledged);
    EXPECT_EQ(state_of(engine, "oven.silent"), AlarmState::returned_unacknowledged);
    EXPECT_EQ(state_of(engine, "kiln.silent"), AlarmState::normal);
    EXPECT_EQ(engine.feed_device("kiln", device::DeviceStatus::wrong_device, t0).at(0).id, "kiln.wrong_device");
}

TEST(AlarmEngine, RestoredStatesCarryOnWithoutARaiseAgain) {
    std::map<std::string, RestoredState> restored;
    restored["oven.temperature_high"] = {AlarmState::active_acknowledged, t0, 260.0, std::nullopt};
    restored["oven.silent"] = {AlarmState::shelved, t0, std::nullopt, t0 + 1h};
    AlarmEngine engine({high_limit(250)}, {"oven"});
    engine.restore(restored);
    EXPECT_EQ(state_of(engine, "oven.temperature_high"), AlarmState::active_acknowledged);
    EXPECT_TRUE(feed(engine, 262, t0 + 1min).empty());  // still high: no second alarm
    EXPECT_EQ(feed(engine, 240, t0 + 2min).at(0).state, AlarmState::normal);
    EXPECT_EQ(state_of(engine, "oven.silent"), AlarmState::shelved);
    EXPECT_EQ(engine.tick(t0 + 1h).at(0).state, AlarmState::normal);
}

}  // namespace
}  // namespace loopwire::gateway::alarms
