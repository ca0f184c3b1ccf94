// The tc10 behaviour model through the wire (tc10-modbus-im05c01e81-03.ru.txt). Each test
// names the manual section its rule comes from. The oven starts at 25 °C with the heater off;
// the factory settings are the simulator's (Pb 20, ti 120 s, td 30 s, output 1 heating,
// output 2 = alarm 1 relay, dP = 0), since the manual lists none.
#include <gtest/gtest.h>

#include <cstdint>

#include "codec/pdu.hpp"
#include "device/models/tc10_simulator.hpp"
#include "device/simulator_harness.hpp"

namespace loopwire::device {
namespace {

using namespace testing;

// §5.1 / §5.2 / §5.3 addresses (Dec column).
constexpr std::uint16_t measured = 1, decimals = 2, working_sp = 3, output_power = 4;
constexpr std::uint16_t alarm_status = 10, output_status = 11, instrument_status = 12;
constexpr std::uint16_t alarm_reset = 13, alarm_acknowledge = 14, control_state = 15;
constexpr std::uint16_t remote_sp = 16, error_output = 18, load_defaults = 19;
constexpr std::uint16_t heating_power = 515, alarm_1_state = 517, alarm_2_state = 518, controller_state = 527;
constexpr std::uint16_t output_1_remote = 548, manual_output = 592;
constexpr std::uint16_t decimal_point = 641, sensor_error_mode = 646, output_1_function = 652;
constexpr std::uint16_t al1_type = 666, al1_function = 667, al1_low = 668, al1_high = 669, al1 = 670;
constexpr std::uint16_t al1_hysteresis = 671, al1_delay = 672, al1_enable = 673, al2_type = 674;
constexpr std::uint16_t proportional_band = 700, integral_time = 701, derivative_time = 702;
constexpr std::uint16_t set_point = 717, remote_sp_type = 722, local_remote = 723;
constexpr std::uint16_t modes_enable = 767, operating_mode = 768, device_address = 769, baud_rate = 770;

constexpr std::uint16_t manual = 1, standby = 2;

// An in-range write must get the standard reply (§4.4 B.1).
void set(Simulated& tc10, std::uint16_t address, int value) {
    const auto request = codec::write_single_register(address, raw(value));
    EXPECT_EQ(tc10.send(request), echo_of(request)) << "write " << value << " to " << address;
}

bool bit(std::uint16_t word, unsigned position) { return ((word >> position) & 1U) != 0; }

SimulationEnvironment at_speed(double speed) {
    SimulationEnvironment environment;
    environment.speed = speed;
    return environment;
}

// --- §3.4 exception 6 and §5.1 19A load defaults -------------------------------------------

TEST(Tc10Model, NotReadyException6WhileLoadingDefaults_Section3_4And5_1_19A) {
    Simulated tc10("tc10");
    set(tc10, load_defaults, 481);  // the command itself gets the standard reply (§4.4 B.1)
    EXPECT_EQ(tc10.send(codec::read_request(codec::FunctionCode::read_holding_registers, 21, 1)), "83 06");
    EXPECT_EQ(tc10.write(set_point, 50), "86 06");
    tc10.wait(0.5);
    EXPECT_EQ(tc10.send(codec::write_multiple_registers(set_point, {50})), "90 06");
    tc10.wait(0.6);
    EXPECT_EQ(tc10.word(21), 20);
    set(tc10, set_point, 50);
}

TEST(Tc10Model, Word19Value481LoadsDefaultsKeepingSerialSettingsAndWorkTime_Section5_1_19A) {
    Simulated tc10("tc10");
    set(tc10, set_point, 150);
    set(tc10, proportional_band, 55);
    set(tc10, remote_sp, 120);
    set(tc10, device_address, 7);
    set(tc10, baud_rate, 3);
    set(tc10, load_defaults, 481);
    tc10.wait(models::Tc10Simulator::defaults_busy_seconds);
    EXPECT_EQ(tc10.word(set_point), 0);
    EXPECT_EQ(tc10.word(6), 0);  // 6A is SP as well
    EXPECT_EQ(tc10.word(proportional_band), 20);
    EXPECT_EQ(tc10.word(remote_sp), 0);
    EXPECT_EQ(tc10.word(device_address), 7);
    EXPECT_EQ(tc10.word(baud_rate), 3);
    EXPECT_EQ(tc10.word(load_defaults), 0);  // a command word, read back as 0
}

TEST(Tc10Model, Word19OtherValuesAreAnsweredAndChangeNothing_Section5_1_19A) {
    Simulated tc10("tc10");
    set(tc10, set_point, 150);
    set(tc10, load_defaults, 480);
    EXPECT_EQ(tc10.word(set_point), 150);  // not busy either
    EXPECT_EQ(tc10.word(load_defaults), 0);
}

// --- §5.1 20A/21A identification -------------------------------------------------------------

TEST(Tc10Model, IdentificationWords20And21_Section5_1_20AAnd21A) {
    Simulated tc10("tc10");
    const Words id = tc10.read(20, 2);
    ASSERT_EQ(id.size(), 2U);
    EXPECT_EQ(id[0] >> 8, 1);      // high byte: protocol family version
    EXPECT_EQ(id[0] & 0xFF, 2);    // low byte: parameter table version
    EXPECT_EQ(id[1], 20);          // 20 = TC10
    EXPECT_EQ(tc10.write(20, 0), "86 02");  // read-only
}

// --- §5.1 15A / §5.3.10 #129, #130 control state -----------------------------------------------

TEST(Tc10Model, ManualHoldsOutputAtManualOutputValue_Section5_1_4A_15A_And5_2_28B) {
    Simulated tc10("tc10");
    set(tc10, manual_output, 3550);  // 35.50 %
    set(tc10, control_state, manual);
    tc10.wait(5);
    EXPECT_EQ(tc10.word(output_power), 3550);
    EXPECT_EQ(tc10.word(514), 3550);
    EXPECT_EQ(tc10.word(heating_power), 3550);
    EXPECT_TRUE(bit(tc10.word(instrument_status), 1));
    EXPECT_EQ(tc10.word(controller_state), 3);  // 12B: 3 = manual
    EXPECT_EQ(tc10.word(operating_mode), manual);
    // Word 4 written in manual sets the manual output.
    set(tc10, output_power, 5000);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(output_power), 5000);
    EXPECT_EQ(tc10.word(manual_output), 5000);
}

TEST(Tc10Model, OutputPowerWrittenInAutomaticIsAnsweredButNotApplied_Section5_1_4A) {
    Simulated tc10("tc10");  // automatic, SP 0 below PV 25: the heater is off
    set(tc10, output_power, 5000);
    tc10.wait(1);
    EXPECT_EQ(tc10.word(output_power), 0);
    EXPECT_EQ(tc10.word(manual_output), 0);
    EXPECT_TRUE(bit(tc10.word(instrument_status), 0));
    EXPECT_EQ(tc10.word(controller_state), 1);
}

TEST(Tc10Model, StandbyTurnsOutputsOffAndInhibitsAlarms_Section5_3_10_130And5_3_3_35) {
    Simulated tc10("tc10");
    set(tc10, set_point, 200);
    set(tc10, al1_type, 1);  // LoAb: 25 <= 100
    set(tc10, al1, 100);
    tc10.wait(1);
    ASSERT_EQ(tc10.word(output_power), 10000);
    ASSERT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, operating_mode, standby);  // oPEr and word 15 are the same state
    tc10.wait(1);
    EXPECT_EQ(tc10.word(control_state), standby);
    EXPECT_EQ(tc10.word(output_power), 0);
    EXPECT_EQ(tc10.word(heating_power), 0);
    EXPECT_EQ(tc10.word(output_status), 0);  // heating relay and alarm relay both off
    EXPECT_EQ(tc10.word(alarm_1_state), 0);  // AL1o = 0: disabled in standby
    EXPECT_FALSE(bit(tc10.word(alarm_status), 0));
    EXPECT_TRUE(bit(tc10.word(instrument_status), 2));
    EXPECT_EQ(tc10.word(controller_state), 0);  // 12B: 0 = standby
    set(tc10, al1_enable, 1);  // AL1o = 1: enabled in standby
    tc10.wait(1);
    EXPECT_EQ(tc10.word(alarm_1_state), 1);
    set(tc10, control_state, 0);  // back to automatic: the PID heats again
    tc10.wait(1);
    EXPECT_EQ(tc10.word(output_power), 10000);
}

TEST(Tc10Model, OprEOffersOnlyItsModes_Section5_3_10_129And4_4B2) {
    Simulated tc10("tc10");
    set(tc10, modes_enable, 1);  // Au.oP: automatic and manual
    EXPECT_EQ(tc10.write(control_state, standby), "86 03");
    EXPECT_EQ(tc10.write(operating_mode, standby), "86 03");
    set(tc10, control_state, manual);
    set(tc10, control_state, 0);
    set(tc10, modes_enable, 2);  // Au.Sb: automatic and standby
    EXPECT_EQ(tc10.write(operating_mode, manual), "86 03");
    set(tc10, operating_mode, standby);
    EXPECT_EQ(tc10.word(control_state), standby);
}

// --- §5.1 16A, 18A: RAM-only values ------------------------------------------------------------

TEST(Tc10Model, RemoteSetPointAndErrorOutputAreLostAtRestart_Section5_1_16A_18A) {
    Simulated before("tc10");
    set(before, remote_sp, 150);
    set(before, error_output, 40);
    set(before, set_point, 180);
    set(before, manual_output, 2500);  // no RAM note in §5.2 28B: saved
    set(before, control_state, manual);
    Simulated after("tc10");
    EXPECT_TRUE(after.device().load_saved(before.device().saved_values()).empty());
    EXPECT_EQ(after.word(remote_sp), 0);
    EXPECT_EQ(after.word(error_output), 0);
    EXPECT_EQ(after.word(set_point), 180);
    EXPECT_EQ(after.word(manual_output), 2500);
    EXPECT_EQ(after.word(control_state), manual);
}

TEST(Tc10Model, RemoteSetPointBecomesWorkingSetPointWhenRemoteSelected_Section5_1_16AAnd5_3_8_84_85) {
    Simulated tc10("tc10");
    set(tc10, set_point, 20);
    set(tc10, remote_sp, 15);
    EXPECT_EQ(tc10.word(working_sp), 20);
    EXPECT_FALSE(bit(tc10.word(instrument_status), 3));
    set(tc10, local_remote, 1);  // rEn
    EXPECT_EQ(tc10.word(working_sp), 15);
    EXPECT_TRUE(bit(tc10.word(instrument_status), 3));
    set(tc10, remote_sp_type, 1);  // trin: local + remote
    EXPECT_EQ(tc10.word(working_sp), 35);
    EXPECT_EQ(tc10.word(520), 35);
}

TEST(Tc10Model, OutputRemoteWordWritableOnlyWhileOutputUnused_Section5_2_13B) {
    Simulated tc10("tc10");  // output 1 is the heating output (o1F = 1)
    EXPECT_EQ(tc10.write(output_1_remote, 1), "86 02");
    set(tc10, output_1_function, 0);
    set(tc10, output_1_remote, 1);
    EXPECT_FALSE(bit(tc10.word(output_status), 0));  // 11A: a serially driven output reads 0
}

// --- §5.3.3 alarms (types #28, function #29, hysteresis #33, delay #34, enable #35) ------------
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

// --- Process (§5.1 1A–4A, §5.2 3B–5B, §5.3.7) --------------------------------------------------

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
    tc10.wait(10);
    EXPECT_NEAR(static_cast<std::int16_t>(tc10.word(measured)), 200, 2);
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

// The manual's own examples write out-of-range values and show normal replies: 10 to bAud
// (770, 0…4; §3.2) and 100 to nSP (10314, 1…4; §3.3). §4.4 B.2 states the rule, and a stated
// rule beats an example: both are refused.
TEST(Tc10Model, ManualExamplesOutOfRangeAreRefusedByTheRangeRule_Section4_4B2_Over3_2And3_3) {
    Simulated tc10("tc10");
    EXPECT_EQ(tc10.write(770, 10), "86 03");
    EXPECT_EQ(tc10.send(codec::write_multiple_registers(10314, {100, 200})), "90 03");
    EXPECT_EQ(tc10.word(770), 0);
}

}  // namespace
}  // namespace loopwire::device
