// The ac20 behaviour model through the wire. Each test names the manual section (ENG. 824E
// rev. 1, English edition) its rule comes from.
#include <gtest/gtest.h>

#include <cmath>

#include "codec/pdu.hpp"
#include "devices/ac20/ac20_atmosphere.hpp"
#include "devices/ac20/ac20_simulator.hpp"
#include "simulation/simulator_harness.hpp"
#include "ac20_test_support.hpp"

namespace loopwire::device {
namespace {

using codec::FunctionCode;
using namespace testing;
using namespace ac20_testing;

// --- Note 5: local/remote ------------------------------------------------------------------

// Note 5: in local "the communication ... is limited to transferring data from slave to
// master ... (with the exception of the local/remote status bit)". Refusal code: 10, "The bit
// or word indicated cannot be modified" (Error reply).
TEST(Ac20Simulator, WritesInLocalAreRefusedWithError10ExceptBit218_Note5) {
    Simulated dev("ac20");
    EXPECT_FALSE(dev.bit(218)) << "power-up in local (Note 5)";
    EXPECT_EQ(dev.write(138, 90), "86 0A");
    EXPECT_EQ(dev.send(codec::write_multiple_registers(138, {90, 90})), "90 0A");
    EXPECT_EQ(set_bit(dev, 219), "85 0A");
    EXPECT_EQ(dev.word(138), 80) << "factory set point 0.80 %C unchanged";
    EXPECT_EQ(set_bit(dev, 218), echo_bit(218));
    EXPECT_TRUE(dev.bit(218));
    EXPECT_EQ(dev.write(138, 90), echo_word(138, 90));
    EXPECT_EQ(dev.word(138), 90);
}

// Note 5: "If there is no line activity for more than 3 sec. every slave will automatically
// return to local mode." The Korean edition says "3초 이상" (3 s or more); the English edition
// wins, so exactly 3 s of silence keeps remote.
TEST(Ac20Simulator, ReturnsToLocalAfterMoreThanThreeSecondsWithoutLineActivity_Note5) {
    Simulated dev("ac20");
    go_remote(dev);
    dev.wait(2.9);
    EXPECT_TRUE(dev.bit(218)) << "2.9 s of silence is not enough";
    dev.wait(3.0);
    EXPECT_TRUE(dev.bit(218)) << "exactly 3 s is not 'more than 3 sec.'";
    dev.wait(3.1);
    EXPECT_FALSE(dev.bit(218));
    EXPECT_EQ(dev.write(138, 90), "86 0A");
}

// Note 5 timeout runs on protocol time: at --speed 100, 2.5 s of real silence (250 s of
// process time) keeps remote.
TEST(Ac20Simulator, RemoteTimeoutIsRealTimeNotScaledBySpeed_Note5) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    go_remote(dev);
    dev.wait(2.5);
    EXPECT_TRUE(dev.bit(218));
    dev.wait(3.5);
    EXPECT_FALSE(dev.bit(218));
}

// Line activity is any request the device receives, also one it does not answer (Error reply:
// no reply for an unimplemented function code).
TEST(Ac20Simulator, UnansweredRequestsAreLineActivity_Note5) {
    Simulated dev("ac20");
    go_remote(dev);
    dev.wait(2.0);
    EXPECT_EQ(dev.send_pdu({0x2B, 0x0E, 0x01, 0x00}), "silence");
    dev.wait(2.0);
    EXPECT_EQ(dev.send_pdu({0x11}), "silence");
    dev.wait(2.0);
    EXPECT_TRUE(dev.bit(218));
}

// --- Notes 6-9: modes and software keys --------------------------------------------------

// Note 7: configuration words are writable only in configuration mode, entered from remote by
// writing the configuration combination (word 4000, factory 0 = any value) to word 347; word
// 135 reads 6. Note 6: control writes and process variables need control mode (8000h there).
// Word 3051 = 1 resets into control mode; Note 5: not in control mode before, so still remote;
// bit 210 signals the start-up.
TEST(Ac20Simulator, ConfigurationModeThroughWord347AndBackThroughWord3051_Notes6And7) {
    Simulated dev("ac20");
    go_remote(dev);
    EXPECT_EQ(dev.write(2000, 1), "86 0A") << "configuration word in control mode";
    EXPECT_EQ(dev.write(3051, 1), "86 0A");
    (void)dev.bit(210);
    ASSERT_EQ(dev.write(347, 42), echo_word(347, 42));
    EXPECT_EQ(dev.word(135), 6);
    EXPECT_EQ(dev.write(2000, 1), echo_word(2000, 1));
    EXPECT_EQ(dev.word(2000), 1);
    EXPECT_EQ(dev.write(138, 90), "86 0A") << "control parameter in configuration mode";
    EXPECT_EQ(dev.word(123), 0x8000) << "carbon potential not available outside control mode";
    EXPECT_EQ(dev.word(122), 0x8000);
    leave_to_control(dev);
    EXPECT_EQ(dev.word(135), 0);
    EXPECT_TRUE(dev.bit(218));
    EXPECT_TRUE(dev.bit(210)) << "start-up flagged";
    EXPECT_NE(dev.word(123), 0x8000);
    EXPECT_EQ(dev.write(138, 90), echo_word(138, 90));
}

// N.B. after Note 9: word 349 locks and unlocks control parameters. The Korean edition once says
// configuration mode is entered through word 349; the English edition (Note 7, N.B.) says 347
// and wins: writing 349 leaves the device in control mode.
TEST(Ac20Simulator, Word349DoesNotEnterConfigurationMode_EnglishNote7OverKorean) {
    Simulated dev("ac20");
    go_remote(dev);
    EXPECT_EQ(dev.write(349, 0), echo_word(349, 0));
    EXPECT_EQ(dev.word(135), 0);
    EXPECT_EQ(dev.write(2000, 1), "86 0A");
}

// Note 8: security words (4000-4011) are always readable, writable only in security code mode
// (word 348 with the configuration combination; word 135 reads 7).
TEST(Ac20Simulator, SecurityWordsWritableOnlyInSecurityCodeMode_Note8) {
    Simulated dev("ac20");
    go_remote(dev);
    EXPECT_EQ(dev.word(4001), 0);
    EXPECT_EQ(dev.write(4001, 77), "86 0A");
    enter_security(dev);
    EXPECT_EQ(dev.write(4001, 77), echo_word(4001, 77));
    EXPECT_EQ(dev.write(2000, 1), "86 0A") << "configuration word in security code mode";
    leave_to_control(dev);
    EXPECT_EQ(dev.word(135), 0);
}

// Note 8 footnote: combination 1 = "no value will be accepted" (error 10); 2-250 = only the
// combination opens (any other value: error 3, illegal data value). Words 347/348/4000 read
// the class 0/1/2, never the key.
TEST(Ac20Simulator, ConfigurationCombinationOneLocksAndAKeyOpens_Note8AndNB) {
    Simulated dev("ac20");
    enter_security(dev);
    ASSERT_EQ(dev.write(4000, 123), echo_word(4000, 123));
    EXPECT_EQ(dev.word(4000), 2);
    leave_to_control(dev);
    EXPECT_EQ(dev.word(347), 2);
    EXPECT_EQ(dev.word(348), 2);
    EXPECT_EQ(dev.write(347, 5), "86 03");
    EXPECT_EQ(dev.word(135), 0);
    EXPECT_EQ(dev.write(348, 123), echo_word(348, 123));
    EXPECT_EQ(dev.word(135), 7);
    ASSERT_EQ(dev.write(4000, 1), echo_word(4000, 1));
    leave_to_control(dev);
    EXPECT_EQ(dev.word(347), 1);
    EXPECT_EQ(dev.write(347, 123), "86 0A");
    EXPECT_EQ(dev.write(348, 1), "86 0A");
    EXPECT_EQ(dev.word(135), 0);
}

// N.B.: control combination 0 forces 4002-4011 to 0 (all free), 1 forces them to 1 (nothing
// can be modified); 349, 350-359 and bit 213 show the lock state.
TEST(Ac20Simulator, ControlCombinationZeroAndOneForceTheGroupWords_NB) {
    Simulated dev("ac20");
    enter_security(dev);
    ASSERT_EQ(dev.write(4001, 1), echo_word(4001, 1));
    EXPECT_EQ(dev.read(4002, 10), Words(10, 1));
    leave_to_control(dev);
    EXPECT_EQ(dev.word(349), 1);
    EXPECT_EQ(dev.read(350, 10), Words(10, 1));
    EXPECT_TRUE(dev.bit(213));
    EXPECT_EQ(dev.write(138, 90), "86 0A");
    EXPECT_EQ(dev.write(349, 1), echo_word(349, 1)) << "349 stays writable while locked";
    EXPECT_EQ(dev.write(138, 90), "86 0A") << "combination 1: always locked";
    enter_security(dev);
    ASSERT_EQ(dev.write(4001, 0), echo_word(4001, 0));
    EXPECT_EQ(dev.read(4002, 10), Words(10, 0));
    leave_to_control(dev);
    EXPECT_EQ(dev.word(349), 0);
    EXPECT_FALSE(dev.bit(213));
    EXPECT_EQ(dev.write(138, 90), echo_word(138, 90));
}

// N.B.: with a combination 2-250, the groups marked in 4002-4011 are locked until 349 receives
// the combination ("It is sufficient to do this once only"); any other value locks again.
// Unprotected groups stay free. 349 reads 2 (locked) / 3 (unlocked); 350-359 per group.
TEST(Ac20Simulator, ControlKeyUnlocksProtectedGroupsThroughWord349_Note9AndNB) {
    Simulated dev("ac20");
    enter_security(dev);
    ASSERT_EQ(dev.write(4001, 77), echo_word(4001, 77));
    ASSERT_EQ(dev.write(4003, 1), echo_word(4003, 1));  // group 1: set points
    leave_to_control(dev);
    EXPECT_EQ(dev.word(349), 2);
    EXPECT_EQ(dev.word(351), 2);
    EXPECT_EQ(dev.word(353), 0) << "group 3 not protected";
    EXPECT_EQ(dev.write(138, 90), "86 0A");
    EXPECT_EQ(dev.write(177, 150), echo_word(177, 150));
    ASSERT_EQ(dev.write(349, 77), echo_word(349, 77));
    EXPECT_EQ(dev.word(349), 3);
    EXPECT_EQ(dev.word(351), 3);
    EXPECT_FALSE(dev.bit(213));
    EXPECT_EQ(dev.write(138, 90), echo_word(138, 90));
    EXPECT_EQ(dev.write(139, 90), echo_word(139, 90)) << "once is enough";
    ASSERT_EQ(dev.write(349, 76), echo_word(349, 76));
    EXPECT_EQ(dev.word(349), 2);
    EXPECT_TRUE(dev.bit(213));
    EXPECT_EQ(dev.write(138, 95), "86 0A");
}

// --- Note 7: end of configuration menu -----------------------------------------------------

// Note 7: words 3000-3005 check "the congruence of the programmed data compared with the data
// of the other configuration menus": dew point as primary variable (menu 1) spans -75..40 °C,
// which the bar-graph scale of menu 6 (0..200) does not fit: closing menu 1 answers 101.
TEST(Ac20Simulator, EndOfMenuOneChecksOtherMenusAndAnswers101_Note7) {
    Simulated dev("ac20");
    enter_configuration(dev);
    EXPECT_EQ(dev.write(3000, 1), echo_word(3000, 1)) << "factory data are congruent";
    ASSERT_EQ(dev.write(2001, 1), echo_word(2001, 1));
    EXPECT_EQ(dev.write(3000, 1), "86 65");
    // Programming or reading another menu closes menu 1 first: refused with the same error.
    EXPECT_EQ(dev.write(2503, 40), "86 65");
    EXPECT_EQ(dev.send(codec::read_request(FunctionCode::read_holding_registers, 2500, 4)), "83 65");
    EXPECT_EQ(dev.send(codec::read_request(FunctionCode::read_input_registers, 2000, 2)), "04 04 00 00 00 01")
        << "reading the open menu itself is fine";
    EXPECT_EQ(dev.write(3051, 1), "86 65") << "leaving configuration mode closes the menu too";
    EXPECT_EQ(dev.word(135), 6);
    ASSERT_EQ(dev.write(2001, 0), echo_word(2001, 0));
    EXPECT_EQ(dev.write(3000, 1), echo_word(3000, 1));
    // Fix menu 6 first, then menu 1 closes cleanly with dew point.
    ASSERT_EQ(dev.write(2503, 40), echo_word(2503, 40));
    ASSERT_EQ(dev.write(3005, 1), echo_word(3005, 1));
    ASSERT_EQ(dev.write(2001, 1), echo_word(2001, 1));
    EXPECT_EQ(dev.write(3000, 1), echo_word(3000, 1));
    leave_to_control(dev);
    EXPECT_EQ(dev.word(300), 0) << "dew point has no decimals";
}

// Note 7, errors 104-106: menu 4 "starts always in manual" without the manual function; menu 5
// a DIG input for auto/manual without it (checked against menu 4); menu 6 bar graph low > high.
TEST(Ac20Simulator, EndOfMenusFourToSixAnswer104To106_Note7) {
    Simulated dev("ac20");
    enter_configuration(dev);
    ASSERT_EQ(dev.write(2302, 0), echo_word(2302, 0));
    ASSERT_EQ(dev.write(2305, 1), echo_word(2305, 1));
    EXPECT_EQ(dev.write(3003, 1), "86 68");
    ASSERT_EQ(dev.write(2305, 0), echo_word(2305, 0));
    ASSERT_EQ(dev.write(3003, 1), echo_word(3003, 1));
    ASSERT_EQ(dev.write(2400, 3), echo_word(2400, 3));
    EXPECT_EQ(dev.write(3004, 1), "86 69");
    ASSERT_EQ(dev.write(2400, 1), echo_word(2400, 1));
    ASSERT_EQ(dev.write(2402, 1), echo_word(2402, 1));
    EXPECT_EQ(dev.write(3004, 1), "86 69") << "DIG1 and DIG2 with the same function";
    ASSERT_EQ(dev.write(2402, 2), echo_word(2402, 2));
    ASSERT_EQ(dev.write(3004, 1), echo_word(3004, 1));
    ASSERT_EQ(dev.write(2502, 150), echo_word(2502, 150));
    ASSERT_EQ(dev.write(2503, 100), echo_word(2503, 100));
    EXPECT_EQ(dev.write(3005, 1), "86 6A");
}

// Note 7, errors 102 and 103: a retransmitting output (2106 = 3, process variable) with its
// scale upside down (2108 > 2109); a scaled main output display (2206 = 1) with 2208 > 2209.
TEST(Ac20Simulator, EndOfMenusTwoAndThreeAnswer102And103_Note7) {
    Simulated dev("ac20");
    enter_configuration(dev);
    ASSERT_EQ(dev.write(2108, 150), echo_word(2108, 150));
    ASSERT_EQ(dev.write(2109, 100), echo_word(2109, 100));
    EXPECT_EQ(dev.write(3001, 1), echo_word(3001, 1)) << "Out 6 not used: its scale does not matter";
    ASSERT_EQ(dev.write(2106, 3), echo_word(2106, 3));
    EXPECT_EQ(dev.write(3001, 1), "86 66");
    ASSERT_EQ(dev.write(2109, 200), echo_word(2109, 200));
    ASSERT_EQ(dev.write(3001, 1), echo_word(3001, 1));
    ASSERT_EQ(dev.write(2208, 500), echo_word(2208, 500));
    ASSERT_EQ(dev.write(2209, 100), echo_word(2209, 100));
    ASSERT_EQ(dev.write(2206, 1), echo_word(2206, 1));
    EXPECT_EQ(dev.write(3002, 1), "86 67");
}

// --- Default loading: word 3050, bits 223-232 ----------------------------------------------

// Word 3050: 2 = TB2 American table: here °F (word 2003 = 4), so the probe temperature word
// (125, "in Celsius or Fahrenheit as configured at Mbus word 2003") reads the same furnace in °F.
TEST(Ac20Simulator, Word3050LoadsTheAmericanTableInFahrenheit_Word3050) {
    Simulated dev("ac20");
    go_remote(dev);
    const double celsius = static_cast<std::int16_t>(dev.word(125));
    EXPECT_NEAR(celsius, 925, 3);
    enter_configuration(dev);
    EXPECT_EQ(dev.write(3050, 2), echo_word(3050, 2));
    EXPECT_EQ(dev.word(2003), 4);
    leave_to_control(dev);
    EXPECT_NEAR(static_cast<std::int16_t>(dev.word(125)), celsius * 9 / 5 + 32, 3);
    enter_configuration(dev);
    EXPECT_EQ(dev.write(3050, 1), echo_word(3050, 1));
    EXPECT_EQ(dev.word(2003), 1);
}

// Bit 223: load default control parameters; "The default value of group 7 (Serial link
// parameters) are not loaded." Bit 225 loads group 1 only.
TEST(Ac20Simulator, Bit223LoadsControlDefaultsExceptGroup7_Bit223) {
    Simulated dev("ac20");
    go_remote(dev);
    ASSERT_EQ(dev.write(138, 120), echo_word(138, 120));
    ASSERT_EQ(dev.write(148, 250), echo_word(148, 250));
    ASSERT_EQ(dev.write(528, 2), echo_word(528, 2));
    EXPECT_EQ(set_bit(dev, 225), echo_bit(225));
    EXPECT_EQ(dev.word(138), 80);
    EXPECT_EQ(dev.word(148), 250) << "bit 225 is group 1 only";
    EXPECT_EQ(set_bit(dev, 223), echo_bit(223));
    EXPECT_EQ(dev.word(148), 100);
    EXPECT_EQ(dev.word(528), 2) << "group 7 kept";
    EXPECT_EQ(set_bit(dev, 231), echo_bit(231));
    EXPECT_EQ(dev.word(528), 5);
}

// Bits 223 and 228: "The command is accepted only if "Smart" (ModBus bit 221) is not active";
// refused with 10. Bit 221 reads tune (211) OR adaptive (212).
TEST(Ac20Simulator, ControlDefaultsRefusedWhileSmartIsActive_Bits221_223_228) {
    Simulated dev("ac20");
    go_remote(dev);
    ASSERT_EQ(set_bit(dev, 221), echo_bit(221));
    EXPECT_TRUE(dev.bit(211));
    EXPECT_TRUE(dev.bit(221));
    EXPECT_EQ(set_bit(dev, 223), "85 0A");
    EXPECT_EQ(set_bit(dev, 228), "85 0A");
    EXPECT_EQ(set_bit(dev, 225), echo_bit(225)) << "other groups load";
    ASSERT_EQ(set_bit(dev, 221, false), echo_bit(221, false));
    EXPECT_FALSE(dev.bit(221));
    EXPECT_EQ(set_bit(dev, 223), echo_bit(223));
}

// --- Unsolicited request flags ---------------------------------------------------------------

// Bit 210: "The bit is set also to signal the start up ... Changes produced by serial link will
// not be flagged. The bit resets after reading." Same for 250-259.
TEST(Ac20Simulator, ChangeFlagsSignalStartUpResetOnReadAndIgnoreSerialChanges_Bits210_250To259) {
    Simulated dev("ac20");
    EXPECT_TRUE(dev.bit(210));
    EXPECT_FALSE(dev.bit(210)) << "reset after reading";
    go_remote(dev);
    ASSERT_EQ(dev.write(138, 90), echo_word(138, 90));
    ASSERT_EQ(dev.write(177, 150), echo_word(177, 150));
    ASSERT_EQ(dev.write(1300, 60), echo_word(1300, 60));
    ASSERT_EQ(set_bit(dev, 310), echo_bit(310));
    EXPECT_FALSE(dev.bit(210));
    EXPECT_EQ(dev.read(250, 10, FunctionCode::read_coils), Words(10, 0));
}

// Bit 252: group 2 is the Smart status (bits 211, 212, 221). The device ending TUNE on its own
// is a change it flags (bits 252 and 210), once; bit 221 stays 1 through adaptive (212).
TEST(Ac20Simulator, TuneEndIsFlaggedInGroup2AndBit221StaysOnThroughAdaptive_Bits221_252) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    (void)dev.bit(210);
    go_remote(dev);
    ASSERT_EQ(set_bit(dev, 221), echo_bit(221));
    EXPECT_FALSE(dev.bit(252)) << "a serial change is not flagged";
    poll(dev, 3.2);
    EXPECT_FALSE(dev.bit(211)) << "TUNE over";
    EXPECT_TRUE(dev.bit(212));
    EXPECT_TRUE(dev.bit(221));
    EXPECT_TRUE(dev.bit(252));
    EXPECT_FALSE(dev.bit(252));
    EXPECT_TRUE(dev.bit(210));
}

// --- Probe test and burn-off: errors 50-55, word 135 -------------------------------------

// Error 52: "not elapsed 5 minutes from power on or from end of another procedure".
TEST(Ac20Simulator, ProceduresWaitFiveMinutesAfterPowerOn_Error52) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    go_remote(dev);
    poll(dev, 2.9);
    EXPECT_EQ(set_bit(dev, 216), "85 34");
    EXPECT_EQ(set_bit(dev, 217), "85 34");
    EXPECT_EQ(dev.word(135), 0);
    poll(dev, 0.2);
    EXPECT_EQ(set_bit(dev, 216), echo_bit(216));
    EXPECT_EQ(dev.word(135), 5);
}

// Word 135 = 5 during the probe test; another procedure is refused with 50; at the end bit 249
// says new data are available (words 127-129), and the 5-minute wait (52) starts again.
TEST(Ac20Simulator, ProbeTestPublishesItsDataAndBlocksOtherProcedures_Word135_Bit249_Errors50And52) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    go_remote(dev);
    past_start_up(dev);
    EXPECT_FALSE(dev.bit(249));
    ASSERT_EQ(set_bit(dev, 216), echo_bit(216));
    EXPECT_EQ(dev.word(135), 5);
    EXPECT_EQ(set_bit(dev, 217), "85 32");
    EXPECT_EQ(set_bit(dev, 216), "85 32");
    poll(dev, 0.7);
    EXPECT_EQ(dev.word(135), 0);
    EXPECT_TRUE(dev.bit(249));
    EXPECT_NEAR(dev.word(127), 480, 30) << "probe resistance, kOhm with 2 decimals";
    EXPECT_EQ(dev.word(128), 125) << "response time 12.5 s";
    EXPECT_NEAR(dev.word(129), 925, 3) << "probe temperature at the test";
    EXPECT_EQ(set_bit(dev, 217), "85 34");
}

// Word 135: burn-off (3) for word 1300 seconds, then purge (4) for word 1301 seconds, then
// control (0).
TEST(Ac20Simulator, BurnOffThenPurgeThenControl_Word135_Words1300And1301) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    go_remote(dev);
    past_start_up(dev);
    ASSERT_EQ(dev.write(1300, 100), echo_word(1300, 100));
    ASSERT_EQ(dev.write(1301, 100), echo_word(1301, 100));
    ASSERT_EQ(set_bit(dev, 217), echo_bit(217));
    EXPECT_EQ(dev.word(135), 3);
    poll(dev, 0.5);
    EXPECT_EQ(dev.word(135), 3);
    poll(dev, 1.0);
    EXPECT_EQ(dev.word(135), 4);
    poll(dev, 1.0);
    EXPECT_EQ(dev.word(135), 0);
}

// Error 51: "the first part of SMART algorithm (TUNE) is in progress".
TEST(Ac20Simulator, ProceduresRefusedDuringSmartTune_Error51) {
    Simulated dev("ac20");
    go_remote(dev);
    ASSERT_EQ(set_bit(dev, 221), echo_bit(221));
    EXPECT_EQ(set_bit(dev, 216), "85 33");
    EXPECT_EQ(set_bit(dev, 217), "85 33");
}

// Error 53: "probe temperature is less than 1000°F/538°": the furnace cools after its burners
// fail (fault heater-failure; 30 min lag, about 17 min to fall below 538 °C).
TEST(Ac20Simulator, ProceduresRefusedWhenTheProbeIsCold_Error53) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    ASSERT_TRUE(dev.device().inject_fault("heater-failure").ok());
    go_remote(dev);
    poll(dev, 12.0);
    EXPECT_LT(static_cast<std::int16_t>(dev.word(125)), 538);
    EXPECT_EQ(set_bit(dev, 217), "85 35");
    EXPECT_EQ(set_bit(dev, 216), "85 35");
}

// Error 54: "probe output is less than 1000 mV" (an air leak makes the atmosphere lean). The
// burn-off does not depend on the probe's output.
TEST(Ac20Simulator, ProbeTestRefusedWithLowProbeOutput_Error54) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    go_remote(dev);
    past_start_up(dev);
    ASSERT_TRUE(dev.device().inject_fault("air-leak").ok());
    poll(dev, 0.2);
    EXPECT_LT(static_cast<std::int16_t>(dev.word(122)), 1000);
    EXPECT_EQ(set_bit(dev, 216), "85 36");
    EXPECT_EQ(set_bit(dev, 217), echo_bit(217));
}

// Error 55: "probe output is unstable (drift > 10 mV/minute)": full enrichment in manual makes
// the probe climb more than 10 mV in a minute.
TEST(Ac20Simulator, ProbeTestRefusedWhileTheProbeDrifts_Error55) {
    Simulated dev("ac20", Model::behaviour, at_speed(10));
    go_remote(dev);
    poll(dev, 31.0);
    ASSERT_EQ(set_bit(dev, 219), echo_bit(219));
    ASSERT_EQ(dev.write(130, 1000), echo_word(130, 1000));
    const double before = static_cast<std::int16_t>(dev.word(122));
    poll(dev, 7.0);
    EXPECT_GT(static_cast<std::int16_t>(dev.word(122)) - before, 10);
    EXPECT_EQ(set_bit(dev, 216), "85 37");
}

// Words 1302 and 1304: an automatic burn-off every 10 minutes; 1304 counts the minutes down
// (7FFFh while no interval is set, as 1305 stays).
TEST(Ac20Simulator, AutomaticBurnOffIntervalCountsDownAndStarts_Words1302And1304) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    go_remote(dev);
    EXPECT_EQ(dev.word(1304), 0x7FFF);
    ASSERT_EQ(dev.write(1302, 10), echo_word(1302, 10));
    EXPECT_EQ(dev.word(1304), 10);
    poll(dev, 3.3);
    EXPECT_EQ(dev.word(1304), 5);
    EXPECT_EQ(dev.word(1305), 0x7FFF);
    EXPECT_EQ(dev.word(135), 0);
    poll(dev, 3.0);
    EXPECT_EQ(dev.word(135), 3) << "burn-off started on its own";
    EXPECT_EQ(dev.word(1304), 10) << "the next one is 10 minutes away";
}

// Word 135: 1 = control mode with error E.130, 2 = E.140; "The error is reset when read if
// device is in remote state" (in local it stays).
TEST(Ac20Simulator, DeviceErrorInWord135ResetsWhenReadInRemote_Word135) {
    Simulated dev("ac20");
    ASSERT_TRUE(dev.device().inject_fault("error-e140").ok());
    EXPECT_EQ(dev.word(135), 2);
    EXPECT_EQ(dev.word(135), 2) << "local: not reset";
    go_remote(dev);
    EXPECT_EQ(dev.word(135), 2);
    EXPECT_EQ(dev.word(135), 0);
}

// --- Identification, buffer overflow ---------------------------------------------------------

// Words 120 (trade mark 50) and 121 (software revision × 100 + identification code 43).
TEST(Ac20Simulator, IdentificationWords_Words120And121) {
    Simulated dev("ac20");
    EXPECT_EQ(dev.word(120), 50);
    const std::uint16_t code = dev.word(121);
    EXPECT_EQ(code % 100, 43);
    EXPECT_EQ(code, models::Ac20Simulator::identification_code);
    EXPECT_GE(code / 100, 1);
}

// Error reply: no reply to "a buffer over flows", error 9 for a count over the limits. The
// manual gives no buffer size; the model takes 64 bytes on the line (61-byte PDU): an FC16 of
// 21..27 words is received and refused with 9, one of 28 words overflows the buffer.
TEST(Ac20Simulator, RequestLongerThanTheReceiveBufferGetsNoReply_ErrorReply) {
    Simulated dev("ac20");  // local: a 20-word write is received, then refused with 10 (Note 5)
    EXPECT_EQ(dev.send(codec::write_multiple_registers(138, Words(20, 90))), "90 0A");
    EXPECT_EQ(dev.send(codec::write_multiple_registers(138, Words(21, 90))), "90 09");
    EXPECT_EQ(dev.send(codec::write_multiple_registers(138, Words(27, 90))), "90 09");
    EXPECT_EQ(dev.send(codec::write_multiple_registers(138, Words(28, 90))), "silence");
    EXPECT_EQ(dev.send(codec::read_request(FunctionCode::read_holding_registers, 120, 21)), "83 09");
    Bytes padded = *codec::encode_request(codec::read_request(FunctionCode::read_holding_registers, 120, 1));
    padded.resize(62, 0);
    EXPECT_EQ(dev.send_pdu(padded), "silence");
}

// --- The process ---------------------------------------------------------------------------

// The AC20 derives carbon potential (123) and dew point (124) from the probe mV (122) and the
// probe temperature (125): the four words agree through the probe equation (ac20_atmosphere.hpp).
TEST(Ac20Simulator, MillivoltsCarbonDewPointAndTemperatureAgree_Words122To125) {
    Simulated dev("ac20");
    const Words words = dev.read(122, 4);
    const double mv = static_cast<std::int16_t>(words[0]);
    const double carbon = static_cast<std::int16_t>(words[1]) / 100.0;
    const double dew = static_cast<std::int16_t>(words[2]);
    const double celsius = static_cast<std::int16_t>(words[3]);
    EXPECT_NEAR(carbon, 0.80, 0.02);
    const auto expected = models::ac20::read_probe(mv, celsius, {0.20, 0.40});
    EXPECT_NEAR(carbon, expected.carbon_percent, 0.02);
    EXPECT_NEAR(dew, expected.dew_point_celsius, 1.5);
}

// Closed loop: a new set point (word 138, 1.00 %C) is reached through the PID output (word
// 130) and the atmosphere; at --speed 100 twenty minutes of furnace time take 12 s.
TEST(Ac20Simulator, CarbonPotentialSettlesAtANewSetPoint_ClosedLoop) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    go_remote(dev);
    ASSERT_EQ(dev.write(138, 100), echo_word(138, 100));
    poll(dev, 0.5);
    EXPECT_GT(dev.word(130), 800) << "output driven up first";
    poll(dev, 12.0);
    EXPECT_NEAR(static_cast<std::int16_t>(dev.word(123)), 100, 2);
    EXPECT_NEAR(dev.word(130), 700, 40) << "steady enrichment for 1.00 %C: (1.00 - 0.30) / 1.00";
    EXPECT_EQ(dev.word(137), 100) << "operative set point";
    EXPECT_EQ(dev.word(136), 1) << "main set point in use";
}

// Word 2001 = 1: dew point as the primary variable (°C, no decimals, word 300 = 0). A lower dew
// point needs a richer atmosphere, so the controller acts in reverse: -10 °C is reached by
// raising the enrichment above the factory 0.80 %C (-5.6 °C).
TEST(Ac20Simulator, DewPointAsPrimaryVariableSettlesReverseActing_Word2001_ClosedLoop) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    enter_configuration(dev);
    ASSERT_EQ(dev.write(2503, 40), echo_word(2503, 40));
    ASSERT_EQ(dev.write(3005, 1), echo_word(3005, 1));
    ASSERT_EQ(dev.write(2001, 1), echo_word(2001, 1));
    ASSERT_EQ(dev.write(3000, 1), echo_word(3000, 1));
    leave_to_control(dev);
    EXPECT_EQ(dev.word(300), 0);
    ASSERT_EQ(dev.write(1011, raw(-75)), echo_word(1011, raw(-75)));
    ASSERT_EQ(dev.write(1012, 40), echo_word(1012, 40));
    ASSERT_EQ(dev.write(138, raw(-10)), echo_word(138, raw(-10)));
    poll(dev, 15.0);
    EXPECT_NEAR(static_cast<std::int16_t>(dev.word(124)), -10, 1);
    EXPECT_GT(static_cast<std::int16_t>(dev.word(123)), 85) << "richer than 0.80 %C";
}

// Bit 219 manual: word 130 holds what the master wrote, and the atmosphere follows it
// (25 % enrichment: 0.30 + 0.25 = 0.55 %C). In auto, word 130 cannot be written (Note 6).
TEST(Ac20Simulator, ManualModeHoldsTheOutputTheMasterWrites_Bit219_Word130) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    go_remote(dev);
    EXPECT_EQ(dev.write(130, 250), "86 0A");
    ASSERT_EQ(set_bit(dev, 219), echo_bit(219));
    ASSERT_EQ(dev.write(130, 250), echo_word(130, 250));
    poll(dev, 12.0);
    EXPECT_EQ(dev.word(130), 250);
    EXPECT_NEAR(static_cast<std::int16_t>(dev.word(123)), 55, 2);
}

// Word 137: a set point written here is used at once, bypassing the gradient (136 = 0), and is
// RAM only: the restart after word 3051 brings the main set point back.
TEST(Ac20Simulator, OperativeSetPointIsUsedAtOnceAndLostAtRestart_Words136And137) {
    Simulated dev("ac20");
    go_remote(dev);
    ASSERT_EQ(dev.write(1013, 1), echo_word(1013, 1));  // main set point ramps 0.01 %C/min
    ASSERT_EQ(dev.write(138, 120), echo_word(138, 120));
    dev.wait(1.0);
    EXPECT_EQ(dev.word(137), 80) << "ramping through the gradient";
    ASSERT_EQ(dev.write(137, 110), echo_word(137, 110));
    EXPECT_EQ(dev.word(137), 110);
    EXPECT_EQ(dev.word(136), 0);
    enter_configuration(dev);
    leave_to_control(dev);
    EXPECT_EQ(dev.word(136), 1);
    EXPECT_EQ(dev.word(137), 120);
}

// Faults drive the measurement words to the manual's codes: open probe input 30005 (over-range)
// on 122, and carbon/dew point then not computable (8000h); open thermocouple 30002 on 125;
// the output falls to its low limit.
TEST(Ac20Simulator, FaultsShowTheManualsErrorCodes_Words122To125) {
    Simulated dev("ac20");
    go_remote(dev);
    ASSERT_TRUE(dev.device().inject_fault("open-probe").ok());
    dev.wait(0.5);
    EXPECT_EQ(dev.word(122), 30005);
    EXPECT_EQ(dev.word(123), 0x8000);
    EXPECT_EQ(dev.word(124), 0x8000);
    EXPECT_EQ(dev.word(130), 0);
    ASSERT_TRUE(dev.device().inject_fault("open-thermocouple").ok());
    EXPECT_EQ(dev.word(125), 30002);
    ASSERT_TRUE(dev.device().inject_fault("none").ok());
    dev.wait(0.5);
    EXPECT_NEAR(static_cast<std::int16_t>(dev.word(125)), 925, 3);
    ASSERT_TRUE(dev.device().inject_fault("auto-zero").ok());
    EXPECT_EQ(dev.read(122, 4), Words(4, 30050));
    EXPECT_FALSE(dev.device().inject_fault("no-such-fault").ok());
}

// --- Alarms: words 113-119, bits 204-206, 222, 233 -------------------------------------------

// Factory alarm 1: high alarm on the process variable at 1.20 %C, automatic reset, action Rev
// (relay de-energised in alarm). Word 119: D8 = 1 entering / 0 leaving, D2-D0 = alarm number.
TEST(Ac20Simulator, AlarmFollowsTheCarbonPotential_Words113_119_Bit204) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    go_remote(dev);
    EXPECT_EQ(dev.word(113), 0);
    EXPECT_TRUE(dev.bit(204)) << "Rev: energised while not in alarm";
    ASSERT_EQ(dev.write(138, 130), echo_word(138, 130));
    poll(dev, 6.0);
    ASSERT_GT(static_cast<std::int16_t>(dev.word(123)), 120);
    EXPECT_EQ(dev.word(113), 1);
    EXPECT_FALSE(dev.bit(204));
    EXPECT_EQ(dev.word(119), 0x101);
    EXPECT_EQ(dev.word(114), 0) << "alarm 2 (low, 0.40 %C) stays off";
    ASSERT_EQ(dev.write(138, 80), echo_word(138, 80));
    poll(dev, 6.0);
    EXPECT_EQ(dev.word(113), 0);
    EXPECT_TRUE(dev.bit(204));
    EXPECT_EQ(dev.word(119), 0x001);
}

// Word 1101 = 4, high alarm with manual reset, action Dir: the alarm stays after the process
// returns (LED flashing: waiting for the operator) until bit 222 resets it.
TEST(Ac20Simulator, ManualResetAlarmWaitsForBit222_Words1101_1102_Bit222) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    go_remote(dev);
    ASSERT_EQ(dev.write(1101, 4), echo_word(1101, 4));
    ASSERT_EQ(dev.write(1102, 1), echo_word(1102, 1));
    EXPECT_FALSE(dev.bit(204));
    ASSERT_EQ(dev.write(138, 130), echo_word(138, 130));
    poll(dev, 6.0);
    EXPECT_EQ(dev.word(113), 1);
    EXPECT_TRUE(dev.bit(204));
    EXPECT_EQ(set_bit(dev, 222), echo_bit(222));
    EXPECT_EQ(dev.word(113), 1) << "still in alarm: a reset does not clear it";
    ASSERT_EQ(dev.write(138, 80), echo_word(138, 80));
    poll(dev, 6.0);
    EXPECT_EQ(dev.word(113), 2);
    EXPECT_TRUE(dev.bit(204));
    EXPECT_EQ(set_bit(dev, 222), echo_bit(222));
    EXPECT_EQ(dev.word(113), 0);
    EXPECT_FALSE(dev.bit(204));
}

// Bit 233 "De-energized all 10 auxiliary outputs" (bits 310-319).
TEST(Ac20Simulator, Bit233SwitchesOffTheAuxiliaryOutputs_Bit233) {
    Simulated dev("ac20");
    go_remote(dev);
    ASSERT_EQ(dev.send(codec::write_multiple_coils(310, {1, 1, 0, 1})), echo_of(codec::write_multiple_coils(310, {1, 1, 0, 1})));
    EXPECT_EQ(dev.read(310, 4, FunctionCode::read_coils), (Words{1, 1, 0, 1}));
    EXPECT_EQ(set_bit(dev, 233), echo_bit(233));
    EXPECT_EQ(dev.read(310, 10, FunctionCode::read_coils), Words(10, 0));
}

// --- The probe equation itself ---------------------------------------------------------------

// 0.80 %C at 925 °C with 20 % CO and 40 % H2: 1134 mV (derivation in ac20_atmosphere.hpp);
// richer atmospheres read higher mV and lower dew points; the inverse gives the carbon back.
TEST(Ac20Atmosphere, ProbeEquationRoundTripsAndOrdersAtmospheres) {
    using namespace models::ac20;
    const double lean = probe_millivolts(oxygen_pressure_for_carbon(0.4, 925), 925);
    const double usual = probe_millivolts(oxygen_pressure_for_carbon(0.8, 925), 925);
    const double rich = probe_millivolts(oxygen_pressure_for_carbon(1.2, 925), 925);
    EXPECT_NEAR(usual, 1134.4, 0.5);
    EXPECT_LT(lean, usual);
    EXPECT_LT(usual, rich);
    EXPECT_NEAR(read_probe(usual, 925).carbon_percent, 0.8, 1e-6);
    EXPECT_GT(read_probe(lean, 925).dew_point_celsius, read_probe(rich, 925).dew_point_celsius);
    EXPECT_NEAR(read_probe(usual, 925).dew_point_celsius, -5.6, 0.1);
}

}  // namespace
}  // namespace loopwire::device
