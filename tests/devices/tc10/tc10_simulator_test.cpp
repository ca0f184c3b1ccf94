// The tc10 behaviour model through the wire (tc10-modbus-im05c01e81-03.ru.txt): the busy
// answer, load defaults, identification, control states, RAM-only values. Alarms and the
// process are in tc10_alarms_test.cpp and tc10_process_test.cpp. Each test names its section.
#include <gtest/gtest.h>

#include <cstdint>
#include <memory>

#include "devices/tc10/tc10_simulator.hpp"

#include "codec/pdu.hpp"
#include "devices/tc10/tc10_test_support.hpp"

namespace loopwire::device {
namespace {

using namespace testing;
using namespace tc10_testing;

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

TEST(Tc10Model, Word19Value481LoadsDefaultsKeepingSerialSettings_Section5_1_19A) {
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

// --- §5.1 16A, 18A, §5.2 28B: RAM-only values ---------------------------------------------------

// §5 lists words 1-29 and 512-592 as computed, dynamically updated values; the remote set point
// (16A), error output (18A) and manual output (28B, also word 4) are lost at power-off;
// the control state (15A) is kept for dSPu = AS.Pr (#128).
TEST(Tc10Model, RemoteSetPointErrorAndManualOutputAreLostAtRestart_Section5_1_16A_18A_And5_2_28B) {
    Simulated before("tc10");
    set(before, remote_sp, 150);
    set(before, error_output, 40);
    set(before, set_point, 180);
    set(before, manual_output, 2500);
    set(before, control_state, manual);
    Simulated after("tc10");
    EXPECT_TRUE(after.device().load_saved(before.device().saved_values()).empty());
    EXPECT_EQ(after.word(remote_sp), 0);
    EXPECT_EQ(after.word(error_output), 0);
    EXPECT_EQ(after.word(set_point), 180);
    EXPECT_EQ(after.word(manual_output), 0);
    EXPECT_EQ(after.word(control_state), manual);
    after.wait(1);
    EXPECT_EQ(after.word(output_power), 0);
}

// dSPu (#128) decides the control state after a restart.
TEST(Tc10Model, PowerOnStateFollowsDSPu_Section5_3_10_128) {
    constexpr std::uint16_t power_on_state = 766;
    Simulated before("tc10");
    set(before, manual_output, 5000);
    set(before, control_state, manual);
    const auto restart_with = [&](int dspu) {
        set(before, power_on_state, dspu);
        auto after = std::make_unique<Simulated>("tc10");
        EXPECT_TRUE(after->device().load_saved(before.device().saved_values()).empty());
        return after;
    };
    auto as_before = restart_with(0);  // AS.Pr: the state kept, the manual output (RAM) not
    EXPECT_EQ(as_before->word(control_state), manual);
    EXPECT_EQ(as_before->word(manual_output), 0);
    auto automatic = restart_with(1);
    EXPECT_EQ(automatic->word(control_state), 0);
    EXPECT_EQ(automatic->word(operating_mode), 0);
    auto manual_zero = restart_with(2);  // oP.0
    EXPECT_EQ(manual_zero->word(control_state), manual);
    manual_zero->wait(1);
    EXPECT_EQ(manual_zero->word(output_power), 0);
    auto in_standby = restart_with(3);
    EXPECT_EQ(in_standby->word(control_state), standby);
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

TEST(Tc10Model, ManualExamplesOutOfRangeAreRefusedByTheRangeRule_Section4_4B2_Over3_2And3_3) {
    Simulated tc10("tc10");
    EXPECT_EQ(tc10.write(770, 10), "86 03");
    EXPECT_EQ(tc10.send(codec::write_multiple_registers(10314, {100, 200})), "90 03");
    EXPECT_EQ(tc10.word(770), 0);
}

}  // namespace
}  // namespace loopwire::device
