// The tc10 process through the wire (tc10-modbus-im05c01e81-03.ru.txt): PV from the oven
// driven by the PID (§5.3.7), output words (§5.1 4A, 11A; §5.2 3B–5B) and input faults
// (§5.1 1A, 12A, 18A).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>

#include "codec/pdu.hpp"
#include "devices/tc10/tc10_test_support.hpp"

namespace loopwire::device {
namespace {

using namespace testing;
using namespace tc10_testing;

TEST(Tc10Model, ClosedLoopSettlesAtTheSetPoint_Section5_3_7) {
    Simulated tc10("tc10", Model::behaviour, at_speed(100));
    EXPECT_EQ(tc10.word(measured), 25);
    set(tc10, set_point, 200);
    for (int i = 0; i < 30; ++i) tc10.wait(1);  // 50 minutes of process time
    const int pv = static_cast<std::int16_t>(tc10.word(measured));
    EXPECT_NEAR(pv, 200, 2);
    // Holding 200 °C takes (200 - 25) / 400 of full power against the loss.
    EXPECT_NEAR(tc10.word(output_power) / 100.0, 43.75, 3.0);
    EXPECT_EQ(tc10.word(working_sp), 200);
    // Settled means steady: over the next 25 minutes the output holds, no limit cycle.
    double low = 100.0, high = 0.0;
    for (int i = 0; i < 30; ++i) {
        tc10.wait(0.5);
        const double output = tc10.word(output_power) / 100.0;
        low = std::min(low, output);
        high = std::max(high, output);
        EXPECT_NEAR(static_cast<std::int16_t>(tc10.word(measured)), 200, 2);
    }
    EXPECT_LT(high - low, 10.0) << "the output cycles between " << low << " and " << high << " %";
}

TEST(Tc10Model, ProportionalBandIsInUnitsScaledByDp_Section5_3_7_62And5_3_1_2) {
    Simulated tc10("tc10");
    set(tc10, integral_time, 0);
    set(tc10, derivative_time, 0);
    set(tc10, proportional_band, 50);
    set(tc10, set_point, 50);  // 25 units below: 25 / 50 = 50 %
    tc10.wait(0.5);            // within the oven's dead time PV has not moved
    EXPECT_EQ(tc10.word(output_power), 5000);
    set(tc10, decimal_point, 1);  // the same raw words now mean 5.0 and 5.0 units
    tc10.wait(0.5);
    EXPECT_EQ(tc10.word(decimals), 1);
    EXPECT_EQ(tc10.word(measured), 250);  // 25.0
    EXPECT_EQ(tc10.word(output_power), 0);  // SP 5.0 below PV 25.0
    set(tc10, proportional_band, 500);  // 50.0
    set(tc10, set_point, 500);          // 50.0
    tc10.wait(0.5);
    EXPECT_EQ(tc10.word(output_power), 5000);
}

TEST(Tc10Model, HeatingRelayIsTimeProportionedOverTcH_Section5_1_11AAnd5_3_7_66) {
    Simulated tc10("tc10");
    set(tc10, manual_output, 5000);
    set(tc10, control_state, manual);
    int on = 0;
    for (int second = 0; second < 20; ++second) {  // tcH = 20.0 s
        tc10.wait(1);
        if (bit(tc10.word(output_status), 0)) ++on;
    }
    EXPECT_NEAR(on, 10, 1);
    set(tc10, output_power, 10000);
    tc10.wait(1);
    EXPECT_TRUE(bit(tc10.word(output_status), 0));
}

TEST(Tc10Model, InputFaultsReadAsTheSpecialValues_Section5_1_1AAnd12A) {
    Simulated tc10("tc10");
    ASSERT_TRUE(tc10.device().inject_fault("open-input").ok());
    EXPECT_EQ(tc10.word(measured), 10000);
    EXPECT_EQ(tc10.word(512), 10000);
    EXPECT_TRUE(bit(tc10.word(instrument_status), 12));
    ASSERT_TRUE(tc10.device().inject_fault("short-input").ok());
    EXPECT_EQ(tc10.word(measured), 10000);
    ASSERT_TRUE(tc10.device().inject_fault("adc-overflow").ok());
    EXPECT_EQ(tc10.word(measured), 10001);
    ASSERT_TRUE(tc10.device().inject_fault("none").ok());
    EXPECT_EQ(tc10.word(measured), 25);
    EXPECT_FALSE(bit(tc10.word(instrument_status), 12));
}

TEST(Tc10Model, MeasurementErrorDrivesTheErrorOutputWhereInECoversIt_Section5_1_18AAnd5_3_1_7) {
    Simulated tc10("tc10");
    set(tc10, error_output, 30);
    ASSERT_TRUE(tc10.device().inject_fault("open-input").ok());  // over-range
    tc10.wait(1);
    EXPECT_EQ(tc10.word(output_power), 3000);  // inE = 0 (or): over-range uses word 18
    set(tc10, sensor_error_mode, 1);           // ou: under-range only
    tc10.wait(1);
    EXPECT_EQ(tc10.word(output_power), 0);
    ASSERT_TRUE(tc10.device().inject_fault("short-input").ok());
    tc10.wait(1);
    EXPECT_EQ(tc10.word(output_power), 3000);
}

// §5.3.2 #14 o1F: 1 = H.rEG "Выход нагрева" works in reverse action (more output as PV falls
// below SP), 2 = c.rEG "Выход охлаждения" in direct action (more output as PV rises above SP).
// Proportional only (ti, td off), read within the oven's dead time so PV stays 25.
TEST(Tc10Model, HeatingIsReverseActionCoolingIsDirectAction_Section5_3_2_14And5_2_4B_5B) {
    constexpr std::uint16_t cooling_power = 516;
    Simulated tc10("tc10");
    set(tc10, integral_time, 0);
    set(tc10, derivative_time, 0);
    const auto output_at = [&](int sp) {
        set(tc10, set_point, sp);
        tc10.wait(0.5);
        return static_cast<int>(static_cast<std::int16_t>(tc10.word(output_power)));
    };
    EXPECT_EQ(output_at(30), 2500);  // heating: PV 5 below SP, Pb 20
    EXPECT_EQ(output_at(35), 5000);
    EXPECT_EQ(output_at(20), 0);     // PV above SP: a heater does nothing
    set(tc10, output_1_function, 2);  // c.rEG
    EXPECT_EQ(output_at(30), 0);      // PV below SP: a cooler does nothing
    EXPECT_EQ(output_at(20), -2500);  // PV 5 above SP: 25 % cooling
    EXPECT_EQ(tc10.word(cooling_power), 2500);
    EXPECT_EQ(tc10.word(heating_power), 0);
    EXPECT_EQ(output_at(15), -5000);  // further above: more cooling
}

TEST(Tc10Model, CoolingOutputPullsTheRunningProcessDownToTheSetPoint_Section5_3_2_14) {
    Simulated tc10("tc10", Model::behaviour, at_speed(100));
    set(tc10, output_1_function, 2);  // c.rEG
    set(tc10, set_point, 15);
    for (int i = 0; i < 30; ++i) tc10.wait(1);  // 50 minutes
    EXPECT_NEAR(static_cast<std::int16_t>(tc10.word(measured)), 15, 1);
    EXPECT_LT(static_cast<std::int16_t>(tc10.word(output_power)), 0);  // holding below ambient
    set(tc10, output_1_function, 1);  // back to heating: it cannot hold 15 below ambient 25
    for (int i = 0; i < 30; ++i) tc10.wait(1);
    EXPECT_EQ(tc10.word(output_power), 0);
    EXPECT_NEAR(static_cast<std::int16_t>(tc10.word(measured)), 25, 1);
}

// §5.3.2 #18 o1Ac: 0 = dir "Прямое действие", 1 = rEU "Обратное действие": a reverse output is
// off while what drives it is on. Output 2 is the alarm 1 relay.
TEST(Tc10Model, ReverseOutputActionInvertsTheOutput_Section5_3_2_18And21) {
    constexpr std::uint16_t output_2_action = 659;
    Simulated tc10("tc10");
    set(tc10, al1_type, 2);  // HiAb 20: the oven at 25 alarms
    set(tc10, al1, 20);
    tc10.wait(1);
    EXPECT_TRUE(bit(tc10.word(output_status), 1));
    set(tc10, output_2_action, 1);  // rEU
    EXPECT_FALSE(bit(tc10.word(output_status), 1));
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, al1, 40);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 0);
    EXPECT_TRUE(bit(tc10.word(output_status), 1));
    set(tc10, output_2_action, 3);  // ReU.r: reverse too
    EXPECT_TRUE(bit(tc10.word(output_status), 1));
    set(tc10, output_2_action, 2);  // dir.r: direct
    EXPECT_FALSE(bit(tc10.word(output_status), 1));
}

// The manual's own examples write out-of-range values and show normal replies: 10 to bAud
// (770, 0…4; §3.2) and 100 to nSP (10314, 1…4; §3.3). §4.4 B.2 states the rule, and a stated
// rule beats an example: both are refused.

}  // namespace
}  // namespace loopwire::device
