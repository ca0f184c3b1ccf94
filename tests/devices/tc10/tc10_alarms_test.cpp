// The tc10 alarms through the wire (tc10-modbus-im05c01e81-03.ru.txt §5.3.3–5.3.5; reset and
// acknowledge §5.1 13A/14A; status words §5.1 10A, 11A, §5.2 6B–8B).
#include <gtest/gtest.h>

#include <cstdint>

#include "codec/pdu.hpp"
#include "devices/tc10/tc10_test_support.hpp"

namespace loopwire::device {
namespace {

using namespace testing;
using namespace tc10_testing;

// The oven sits at 25 °C with the heater off (SP 0), so thresholds move around a steady PV.

TEST(Tc10Model, AbsoluteHighAlarmWithHysteresis_Section5_3_3_28And33) {
    Simulated tc10("tc10");
    set(tc10, al1_type, 2);  // HiAb
    set(tc10, al1_hysteresis, 5);
    set(tc10, al1, 25);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    EXPECT_TRUE(bit(tc10.word(alarm_status), 0));
    EXPECT_TRUE(bit(tc10.word(output_status), 1));  // output 2 = alarm 1 relay
    set(tc10, al1, 27);  // PV below the threshold but within the hysteresis: stays on
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, al1, 31);  // 25 <= 31 - 5: off
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
    set(tc10, al1, 27);  // from off, only PV >= 27 switches on
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
    EXPECT_EQ(tc10.word(alarm_status), 0);
}

TEST(Tc10Model, AbsoluteLowAlarm_Section5_3_3_28) {
    Simulated tc10("tc10");
    set(tc10, al1_type, 1);  // LoAb
    set(tc10, al1, 30);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, al1, 20);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
}

TEST(Tc10Model, DeviationAlarmsFollowTheSetPoint_Section5_3_3_28) {
    Simulated tc10("tc10");
    set(tc10, al1_type, 7);  // HidE: PV >= SP + AL1
    set(tc10, al1, 20);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);  // 25 >= 0 + 20
    set(tc10, set_point, 10);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);  // 25 < 10 + 20 - 1
    set(tc10, al1_type, 6);  // LodE: PV <= SP + AL1
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);  // 25 <= 30
    set(tc10, set_point, -10);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);  // 25 > -10 + 20
}

TEST(Tc10Model, AbsoluteBandAlarmsOutsideAndInside_Section5_3_3_28And30_31) {
    Simulated tc10("tc10");
    set(tc10, al1_low, 20);
    set(tc10, al1_high, 30);
    set(tc10, al1_type, 3);  // LHAo
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
    set(tc10, al1_low, 26);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, al1_type, 4);  // LHAi
    set(tc10, al1_low, 20);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, al1_high, 24);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
}

TEST(Tc10Model, RelativeBandAlarmMovesWithTheSetPoint_Section5_3_3_28) {
    Simulated tc10("tc10");
    set(tc10, al1_low, 10);
    set(tc10, al1_high, 30);
    set(tc10, al1_type, 8);  // LHdo: outside [SP + 10, SP + 30]
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
    set(tc10, set_point, 20);  // band 30…50
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, al1_type, 9);  // LHdi: inside the band
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
}

TEST(Tc10Model, LatchedAlarmStaysUntilResetByWord13_Section5_3_3_29And5_1_13A) {
    Simulated tc10("tc10");
    set(tc10, al1_type, 2);
    set(tc10, al1_function, 2);  // latched
    set(tc10, al1, 20);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, alarm_reset, 1);  // the condition lasts: a reset does nothing
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, al1, 40);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);  // condition gone, still latched
    set(tc10, alarm_reset, 1);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
    EXPECT_EQ(tc10.word(alarm_reset), 0);
}

TEST(Tc10Model, AcknowledgeableAlarmGoesOffOnWord14UntilItRecurs_Section5_3_3_29And5_1_14A) {
    Simulated tc10("tc10");
    set(tc10, al1_type, 2);
    set(tc10, al1, 20);
    tc10.wait(1);
    set(tc10, alarm_acknowledge, 1);  // Ab1 = 0: not acknowledgeable
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, al1_function, 4);  // acknowledgeable
    set(tc10, alarm_acknowledge, 1);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
    EXPECT_FALSE(bit(tc10.word(output_status), 1));
    set(tc10, al1, 40);
    tc10.wait(1);
    set(tc10, al1, 20);  // a new occurrence alarms again
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
}

TEST(Tc10Model, AlarmNotActiveAtPowerOnWaitsForTheConditionToClear_Section5_3_3_29) {
    Simulated before("tc10");
    set(before, al1_type, 2);      // HiAb 20: the oven at 25 is in alarm
    set(before, al1_function, 1);  // +1 not active at power-on
    set(before, al1, 20);
    Simulated after("tc10");  // a restart with those settings
    ASSERT_TRUE(after.device().load_saved(before.device().saved_values()).empty());
    after.wait(1);
    EXPECT_EQ(after.word(alarm_1_state), 0);
    set(after, al1, 40);  // the condition clears once…
    after.wait(1);
    set(after, al1, 20);  // …and from then on alarms as usual
    after.wait(1);
    EXPECT_EQ(after.word(alarm_1_state), 1);
    // Without +1 the same restart alarms at once.
    set(before, al1_function, 0);
    Simulated plain("tc10");
    ASSERT_TRUE(plain.device().load_saved(before.device().saved_values()).empty());
    plain.wait(1);
    EXPECT_EQ(plain.word(alarm_1_state), 1);
}

TEST(Tc10Model, RelativeAlarmNotActiveAtSetPointChange_Section5_3_3_29) {
    Simulated tc10("tc10");
    set(tc10, control_state, manual);  // output 0: the oven stays at 25 whatever the SP
    set(tc10, al1_type, 7);            // HidE: PV >= SP + 10
    set(tc10, al1, 10);
    set(tc10, set_point, 100);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
    set(tc10, al1_function, 8);  // +8 not active at set-point change
    set(tc10, set_point, 0);     // 25 >= 10, but the SP just moved
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
    set(tc10, al1, 30);  // the condition clears…
    tc10.wait(1);
    set(tc10, al1, 10);  // …and returns without an SP change: alarm
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, al1_function, 0);
    set(tc10, set_point, 100);
    tc10.wait(1);
    set(tc10, set_point, 0);  // without +8 the SP change alarms at once
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
}

TEST(Tc10Model, AlarmDelayHoldsTheAlarmBack_Section5_3_3_34) {
    Simulated tc10("tc10");
    set(tc10, al1_type, 2);
    set(tc10, al1_delay, 5);
    set(tc10, al1, 20);
    tc10.wait(3);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
    tc10.wait(3);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
}

TEST(Tc10Model, SensorBreakAlarmAndOutOfRangeEnable_Section5_3_3_28And35) {
    Simulated tc10("tc10");
    set(tc10, al2_type, 5);  // SE.br
    set(tc10, al1_type, 2);  // HiAb far above the oven
    set(tc10, al1, 900);
    ASSERT_TRUE(tc10.device().inject_fault("open-input").ok());
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_2_state), 1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);  // AL1o = 0: disabled out of range
    EXPECT_TRUE(bit(tc10.word(alarm_status), 11));  // general error
    set(tc10, al1_enable, 2);  // enabled out of range: an open input reads over any threshold
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    ASSERT_TRUE(tc10.device().inject_fault("none").ok());
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_status), 0);
}

}  // namespace
}  // namespace loopwire::device
