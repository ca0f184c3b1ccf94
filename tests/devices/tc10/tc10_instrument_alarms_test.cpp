// The tc10's instrument alarms through the wire (tc10-modbus-im05c01e81-03.ru.txt): the loop
// break alarm (§5.3.6 #52–#55; §5.1 10A bit 9, §5.2 10B), the power failure indicator (§5.1 10A
// bit 10; o<n>F 13 P.FAL, 14 bo.PF) and the output 4 overload (§5.1 10A bit 12, §5.2 11B,
// o<n>AL +32).
#include <gtest/gtest.h>

#include <cstdint>

#include "codec/pdu.hpp"
#include "devices/tc10/tc10_test_support.hpp"

namespace loopwire::device {
namespace {

using namespace testing;
using namespace tc10_testing;

constexpr std::uint16_t loop_break_state = 522, overload_state = 526;
constexpr std::uint16_t io4_function = 648, output_3_function = 660, output_3_alarms = 661;
constexpr std::uint16_t lba_time = 690, lba_delta = 692, lba_condition = 693;
constexpr int function_alarm = 3, function_power_failure = 13, function_burnout_or_power = 14;
constexpr unsigned output_3_bit = 3;  // §5.1 11A prints output 3 at bit 3

// LbAt 30 s, LbAS 5 units, LbcA uP; output 3 is the LBA relay (o3AL +8).
void arm_loop_break(Simulated& tc10, int condition = 0) {
    set(tc10, lba_time, 30);
    set(tc10, lba_delta, 5);
    set(tc10, lba_condition, condition);
    set(tc10, output_3_function, function_alarm);
    set(tc10, output_3_alarms, 8);
}

// #52 LbAt "Время сигнализации обрыва цепи", #54 LbAS "Мера разности, используемая сигнализацией
// обрыва цепи", #55 LbcA 0 = uP "Активна, когда Pout = 100%".
TEST(Tc10Model, LoopBreakAlarmWhenPvDoesNotAnswerAFullOutputWithinLbAt_Section5_3_6_52_54_55) {
    Simulated tc10("tc10");
    arm_loop_break(tc10);
    ASSERT_TRUE(tc10.device().inject_fault("loop-break").ok());  // the heater is disconnected
    set(tc10, set_point, 200);  // PV 25: the output goes to 100 %
    tc10.wait(29);
    EXPECT_EQ(tc10.word(output_power), 10000);
    EXPECT_EQ(tc10.word(loop_break_state), 0);
    EXPECT_FALSE(bit(tc10.word(alarm_status), 9));
    tc10.wait(2);
    EXPECT_EQ(tc10.word(loop_break_state), 1);
    EXPECT_TRUE(bit(tc10.word(alarm_status), 9));
    EXPECT_TRUE(bit(tc10.word(output_status), output_3_bit));
    EXPECT_EQ(static_cast<std::int16_t>(tc10.word(measured)), 25);
    // The heater reconnected: once PV has risen by LbAS the alarm is over.
    ASSERT_TRUE(tc10.device().inject_fault("none").ok());
    tc10.wait(20);
    EXPECT_GT(static_cast<std::int16_t>(tc10.word(measured)), 30);
    EXPECT_EQ(tc10.word(loop_break_state), 0);
    EXPECT_FALSE(bit(tc10.word(alarm_status), 9));
    EXPECT_FALSE(bit(tc10.word(output_status), output_3_bit));
}

TEST(Tc10Model, NoLoopBreakAlarmWhileTheProcessAnswers_Section5_3_6_52) {
    Simulated tc10("tc10");
    arm_loop_break(tc10);
    set(tc10, set_point, 300);
    for (int i = 0; i < 12; ++i) {  // two minutes at 100 %: PV rises far more than 5 per 30 s
        tc10.wait(10);
        EXPECT_EQ(tc10.word(output_power), 10000);
        EXPECT_EQ(tc10.word(loop_break_state), 0);
    }
}

// #55 LbcA 1 = dn watches -100 % only; #52 LbAt 0 = oFF.
TEST(Tc10Model, LoopBreakAlarmOnlyForTheOutputLbcASelectsAndNotWhenOff_Section5_3_6_52_55) {
    Simulated tc10("tc10");
    arm_loop_break(tc10, 1);  // dn
    ASSERT_TRUE(tc10.device().inject_fault("loop-break").ok());
    set(tc10, set_point, 200);  // +100 %
    tc10.wait(40);
    EXPECT_EQ(tc10.word(loop_break_state), 0);
    set(tc10, lba_condition, 2);  // both: +100 % counts now
    tc10.wait(31);
    EXPECT_EQ(tc10.word(loop_break_state), 1);
    set(tc10, lba_time, 0);  // oFF
    tc10.wait(1);
    EXPECT_EQ(tc10.word(loop_break_state), 0);
}

// §5.1 10A bit 10 "Индикатор сбоя питания". Chosen: on after a restart from saved contents (the
// controller was powered off), off on a first power-up, cleared by an alarm reset (word 13).
TEST(Tc10Model, PowerFailureIndicatorAfterARestartUntilAlarmReset_Section5_1_10A_Bit10And5_3_2_14) {
    Simulated before("tc10");
    set(before, output_3_function, function_power_failure);  // P.FAL
    before.wait(1);
    EXPECT_FALSE(bit(before.word(alarm_status), 10));
    EXPECT_FALSE(bit(before.word(output_status), output_3_bit));
    Simulated after("tc10");
    ASSERT_TRUE(after.device().load_saved(before.device().saved_values()).empty());
    after.wait(1);
    EXPECT_TRUE(bit(after.word(alarm_status), 10));
    EXPECT_TRUE(bit(after.word(output_status), output_3_bit));
    set(after, output_3_function, function_burnout_or_power);  // bo.PF: power failure too
    EXPECT_TRUE(bit(after.word(output_status), output_3_bit));
    set(after, alarm_reset, 1);
    EXPECT_FALSE(bit(after.word(alarm_status), 10));
    EXPECT_FALSE(bit(after.word(output_status), output_3_bit));
}

// §5.2 11B "Состояние сигнализации перегрузки"; §5.3.2 #17 "+32 = Перегрузка на выходе 4".
TEST(Tc10Model, OutputFourOverloadAlarm_Section5_2_11BAnd5_1_10A_Bit12) {
    Simulated tc10("tc10");
    set(tc10, output_3_function, function_alarm);
    set(tc10, output_3_alarms, 32);
    EXPECT_EQ(tc10.word(overload_state), 0);
    ASSERT_TRUE(tc10.device().inject_fault("output-4-overload").ok());
    EXPECT_EQ(tc10.word(overload_state), 1);
    EXPECT_TRUE(bit(tc10.word(alarm_status), 12));
    EXPECT_TRUE(bit(tc10.word(output_status), output_3_bit));
    set(tc10, io4_function, 2);  // I/O 4 as a digital input: no output 4 to overload
    EXPECT_EQ(tc10.word(overload_state), 0);
    EXPECT_FALSE(bit(tc10.word(alarm_status), 12));
    set(tc10, io4_function, 1);  // out4
    EXPECT_EQ(tc10.word(overload_state), 1);
    ASSERT_TRUE(tc10.device().inject_fault("none").ok());
    EXPECT_EQ(tc10.word(overload_state), 0);
    EXPECT_FALSE(bit(tc10.word(output_status), output_3_bit));
}

}  // namespace
}  // namespace loopwire::device
