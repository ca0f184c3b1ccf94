// The tc10 set-point ramp through the wire (tc10-modbus-im05c01e81-03.ru.txt §5.3.8 #86 SP.u,
// #87 SP.d; working set point §5.1 3A; ramp status §5.1 12A bit 9).
#include <gtest/gtest.h>

#include <cstdint>
#include <memory>

#include "codec/pdu.hpp"
#include "devices/tc10/tc10_test_support.hpp"

namespace loopwire::device {
namespace {

using namespace testing;
using namespace tc10_testing;

constexpr std::uint16_t ramp_up = 724, ramp_down = 725;  // SP.u, SP.d: units per minute, 2 decimals
constexpr int infinite_rate = 9999;                       // 99.99 = inF
constexpr unsigned ramp_bit = 9;  // §5.1 12A "Выполняется линейное изменение для уставки"

int working(Simulated& tc10) { return static_cast<std::int16_t>(tc10.word(working_sp)); }

// #86 "Скорость нарастания для ПОЛОЖИТЕЛЬНОГО изменения уставки (повышение) … ед. измерения в
// минуту", #87 the same for a negative change; 99.99 (inF) steps.
TEST(Tc10Model, WorkingSetPointRampsAtSPuAndSPdWhileBit9IsSet_Section5_3_8_86_87And5_1_12A) {
    Simulated tc10("tc10");
    set(tc10, ramp_up, 6000);  // 60.00 units per minute: 1 per second
    tc10.wait(1);
    EXPECT_EQ(working(tc10), 0);  // SP 0, falling with SP.d = inF: no ramp
    EXPECT_FALSE(bit(tc10.word(instrument_status), ramp_bit));
    set(tc10, set_point, 100);
    tc10.wait(10);
    EXPECT_NEAR(working(tc10), 10, 1);
    EXPECT_TRUE(bit(tc10.word(instrument_status), ramp_bit));
    EXPECT_EQ(tc10.word(520), tc10.word(working_sp));  // §5.2 9B "Как адрес 3"
    tc10.wait(40);
    EXPECT_NEAR(working(tc10), 50, 1);
    tc10.wait(55);
    EXPECT_EQ(working(tc10), 100);
    EXPECT_FALSE(bit(tc10.word(instrument_status), ramp_bit));
    set(tc10, ramp_down, 3000);  // 30.00 per minute: 0.5 per second down
    set(tc10, set_point, 50);
    tc10.wait(20);
    EXPECT_NEAR(working(tc10), 90, 1);
    EXPECT_TRUE(bit(tc10.word(instrument_status), ramp_bit));
    set(tc10, ramp_down, infinite_rate);  // inF: the rest of the change is a step
    tc10.wait(0.5);
    EXPECT_EQ(working(tc10), 50);
    EXPECT_FALSE(bit(tc10.word(instrument_status), ramp_bit));
}

// The rate is in units per minute with its own two decimals, not in dP counts.
TEST(Tc10Model, RampRateIsUnitsPerMinuteWhateverDp_Section5_3_8_86) {
    Simulated tc10("tc10");
    set(tc10, decimal_point, 1);
    set(tc10, ramp_up, 600);  // 6.00 units per minute: 0.1 per second
    tc10.wait(1);
    set(tc10, set_point, 1000);  // 100.0
    tc10.wait(30);
    EXPECT_NEAR(working(tc10), 30, 1);  // 3.0 units, in tenths
}

// The manual does not say where a ramp starts; chosen: from the measured value at power-on and
// on each return to automatic. Manual and standby work to no set point: word 3 shows the final one.
TEST(Tc10Model, RampStartsFromTheMeasuredValueAtPowerOnAndBackInAutomatic_Section5_3_8_86) {
    Simulated before("tc10");
    set(before, ramp_up, 6000);
    set(before, set_point, 100);
    Simulated after("tc10");  // a restart with those settings
    ASSERT_TRUE(after.device().load_saved(before.device().saved_values()).empty());
    after.wait(5);
    EXPECT_NEAR(working(after), 30, 1);  // from PV 25 at 1 unit per second
    set(after, control_state, manual);
    after.wait(1);
    EXPECT_EQ(working(after), 100);
    EXPECT_FALSE(bit(after.word(instrument_status), ramp_bit));
    set(after, control_state, 0);  // automatic again: from PV, not where the ramp had got to
    after.wait(5);
    const int pv = static_cast<std::int16_t>(after.word(measured));
    EXPECT_NEAR(working(after), pv + 5, 2);
    EXPECT_TRUE(bit(after.word(instrument_status), ramp_bit));
}

// The PID works to the working set point: while the ramp is low the output is small.
TEST(Tc10Model, ControlFollowsTheRampNotTheFinalSetPoint_Section5_3_8_86And5_1_3A) {
    Simulated tc10("tc10");
    set(tc10, integral_time, 0);
    set(tc10, derivative_time, 0);
    set(tc10, ramp_up, 600);  // 0.1 unit per second
    tc10.wait(1);
    set(tc10, set_point, 200);
    tc10.wait(5);  // within the dead time: PV 25, working SP 25.5
    EXPECT_LT(tc10.word(output_power), 1000);  // far from the 100 % a step to 200 gives
    set(tc10, ramp_up, infinite_rate);
    tc10.wait(0.5);
    EXPECT_EQ(tc10.word(output_power), 10000);
}

}  // namespace
}  // namespace loopwire::device
