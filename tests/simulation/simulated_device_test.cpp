// The profile-driven simulators through the wire: encoded request PDUs go into handle(), the
// replies are decoded (docs/DESIGN.md: never poke the model's internals). Each test cites the manual
// section or profile field its rule comes from.
#include <gtest/gtest.h>

#include "codec/pdu.hpp"
#include "simulation/simulated_device.hpp"
#include "simulator_harness.hpp"

namespace loopwire::device {
namespace {

using codec::FunctionCode;
using namespace testing;

// --- TC10 (tc10-modbus-im05c01e81-03.ru.txt) ---------------------------------------------

TEST(SimulatedTc10, Word21ReadsTwentySoScanIdentifiesIt_Section5_1_21A) {
    Simulated tc10("tc10", Model::profile_only);
    EXPECT_EQ(tc10.word(21), 20);
}

TEST(SimulatedTc10, FunctionOutsideThreeSixSixteenGetsException1_Section3_4) {
    Simulated tc10("tc10", Model::profile_only);
    EXPECT_EQ(tc10.send(codec::read_request(FunctionCode::read_input_registers, 1, 1)), "84 01");
    EXPECT_EQ(tc10.send_pdu({0x2B, 0x0E, 0x01, 0x00}), "AB 01");
}

TEST(SimulatedTc10, MoreThanSixteenRegistersGetsException3_Sections3_1And3_3) {
    Simulated tc10("tc10", Model::profile_only);
    EXPECT_EQ(tc10.read(640, 16).size(), 16U);
    EXPECT_EQ(tc10.send(codec::read_request(FunctionCode::read_holding_registers, 640, 17)), "83 03");
    EXPECT_EQ(tc10.send(codec::write_multiple_registers(640, Words(17, 0))), "90 03");
}

TEST(SimulatedTc10, RangeTouchingAnUnlistedAddressGetsException2_Section3_4) {
    Simulated tc10("tc10", Model::profile_only);
    EXPECT_EQ(tc10.send(codec::read_request(FunctionCode::read_holding_registers, 30, 1)), "83 02");
    EXPECT_EQ(tc10.send(codec::read_request(FunctionCode::read_holding_registers, 28, 3)), "83 02");
    EXPECT_EQ(tc10.send(codec::write_single_register(30, 1)), "86 02");
}

TEST(SimulatedTc10, SettingParametersAnswerAtBothRanges_Section5AreaTable) {
    Simulated tc10("tc10", Model::profile_only);
    const auto write = codec::write_single_register(717 + 9600, 123);  // SP at 10317 (2CD / 284D)
    EXPECT_EQ(tc10.send(write), echo_of(write));
    EXPECT_EQ(tc10.word(717), 123);
    EXPECT_EQ(tc10.read(10240, 4), tc10.read(640, 4));
}

TEST(SimulatedTc10, ReadOnlyWordWriteGetsException2AndIsNotStored_Section3_4) {
    Simulated tc10("tc10", Model::profile_only);
    EXPECT_EQ(tc10.send(codec::write_single_register(21, 7)), "86 02");
    EXPECT_EQ(tc10.word(21), 20);
}

TEST(SimulatedTc10, SetPointAboveSpHlIsRefusedWithException3_Section4_4B) {
    Simulated tc10("tc10", Model::profile_only);
    EXPECT_EQ(tc10.send(codec::write_single_register(716, 100)), echo_of(codec::write_single_register(716, 100)));
    EXPECT_EQ(tc10.send(codec::write_single_register(717, 50)), echo_of(codec::write_single_register(717, 50)));
    EXPECT_EQ(tc10.send(codec::write_single_register(717, 150)), "86 03");
    EXPECT_EQ(tc10.word(717), 50);
    // A limit itself cannot cross the other limit (SP.HL min = SP.LL).
    EXPECT_EQ(tc10.send(codec::write_single_register(715, 101)), "86 03");
}

TEST(SimulatedTc10, Fc16BoundsUseValuesEarlierInTheSameRequest_Section4_4B) {
    Simulated tc10("tc10", Model::profile_only);
    // SP.LL, SP.HL, SP at 715-717 in one request: SP is checked against the new limits.
    const auto ok = codec::write_multiple_registers(715, {raw(-10), 500, 400});
    EXPECT_EQ(tc10.send(ok), echo_of(ok));
    EXPECT_EQ(tc10.read(715, 3), (Words{raw(-10), 500, 400}));
}

TEST(SimulatedTc10, Fc16WithOneBadValueLeavesMemoryUnchanged_Section4_4B) {
    Simulated tc10("tc10", Model::profile_only);
    const Words before = tc10.read(715, 3);
    EXPECT_EQ(tc10.send(codec::write_multiple_registers(715, {0, 100, 200})), "90 03");
    EXPECT_EQ(tc10.read(715, 3), before);
}

TEST(SimulatedTc10, BroadcastWriteIsExecutedAndNotAnswered_Section3) {
    Simulated tc10("tc10", Model::profile_only);
    EXPECT_EQ(tc10.send(codec::write_single_register(717, 42), true), "silence");
    EXPECT_EQ(tc10.word(717), 42);
}

// --- Ramp/soak controller (rampsoak-pid-rtu-ascii-linking.en.txt) ------------------------

TEST(SimulatedRampSoak, VerReads104SoScanIdentifiesIt_Section7) {
    Simulated rampsoak("rampsoak", Model::profile_only);
    EXPECT_EQ(rampsoak.word(0x86), 104);
}

TEST(SimulatedRampSoak, ManualFc16ExampleIsEchoed_Section4_7_3) {
    Simulated rampsoak("rampsoak", Model::profile_only);
    // §4.7.3: 01 10 00 00 00 02 04 00 64 03 E8 -> 01 10 00 00 00 02 (SV = 100, OUTL = 1000).
    EXPECT_EQ(rampsoak.send_pdu({0x10, 0x00, 0x00, 0x00, 0x02, 0x04, 0x00, 0x64, 0x03, 0xE8}), "10 00 00 00 02");
    EXPECT_EQ(rampsoak.read(0, 2), (Words{100, 1000}));
}

TEST(SimulatedRampSoak, UnsupportedFunctionGetsException1_Section4_6) {
    Simulated rampsoak("rampsoak", Model::profile_only);
    EXPECT_EQ(rampsoak.send(codec::read_request(FunctionCode::read_coils, 0, 1)), "81 01");
}

TEST(SimulatedRampSoak, MoreThanEightRegistersGetsException3_Section4) {
    Simulated rampsoak("rampsoak", Model::profile_only);
    EXPECT_EQ(rampsoak.read(0, 8).size(), 8U);
    EXPECT_EQ(rampsoak.send(codec::read_request(FunctionCode::read_holding_registers, 0, 9)), "83 03");
    EXPECT_EQ(rampsoak.send(codec::write_multiple_registers(0, Words(9, 0))), "90 03");
}

TEST(SimulatedRampSoak, UndefinedGapGetsException2_Sections4_6And7) {
    Simulated rampsoak("rampsoak", Model::profile_only);
    EXPECT_EQ(rampsoak.send(codec::read_request(FunctionCode::read_holding_registers, 0x78, 1)), "83 02");
    EXPECT_EQ(rampsoak.send(codec::read_request(FunctionCode::read_holding_registers, 0x75, 4)), "83 02");
}

TEST(SimulatedRampSoak, ReadOnlyRegisterWriteGetsException2_Section7) {
    Simulated rampsoak("rampsoak", Model::profile_only);
    EXPECT_EQ(rampsoak.send(codec::write_single_register(0x86, 1)), "86 02");
    EXPECT_EQ(rampsoak.word(0x86), 104);
}

TEST(SimulatedRampSoak, OutlAboveHundredPercentGetsException3_Section7) {
    Simulated rampsoak("rampsoak", Model::profile_only);
    EXPECT_EQ(rampsoak.send(codec::write_single_register(1, 1001)), "86 03");
    EXPECT_EQ(rampsoak.send(codec::write_multiple_registers(0, {5, 1001})), "90 03");
    EXPECT_EQ(rampsoak.read(0, 2), (Words{0, 0}));  // all or nothing
}

TEST(SimulatedRampSoak, BroadcastIsNotExecuted_ProfileBroadcastFalse) {
    Simulated rampsoak("rampsoak", Model::profile_only);
    EXPECT_EQ(rampsoak.send(codec::write_single_register(0, 77), true), "silence");
    EXPECT_EQ(rampsoak.word(0), 0);
}

// --- AC20 (ac20-modbus-jbus-eng824e.en.txt) ----------------------------------------------

TEST(SimulatedAc20, Word120ReadsFiftySoScanIdentifiesIt_Word120) {
    Simulated ac20("ac20", Model::profile_only);
    EXPECT_EQ(ac20.word(120), 50);
}

TEST(SimulatedAc20, UnimplementedFunctionGetsNoReplyAtAll_ErrorReply) {
    Simulated ac20("ac20", Model::profile_only);
    EXPECT_EQ(ac20.send_pdu({0x2B, 0x0E, 0x01, 0x00}), "silence");
    EXPECT_EQ(ac20.send_pdu({0x07}), "silence");
}

TEST(SimulatedAc20, OverTwentyWordsOrTwentyFourBitsGetsError9_FunctionCodes1To16) {
    Simulated ac20("ac20", Model::profile_only);
    EXPECT_EQ(ac20.read(120, 20).size(), 20U);
    EXPECT_EQ(ac20.send(codec::read_request(FunctionCode::read_holding_registers, 120, 21)), "83 09");
    EXPECT_EQ(ac20.send(codec::read_request(FunctionCode::read_input_registers, 120, 21)), "84 09");
    EXPECT_EQ(ac20.send(codec::read_request(FunctionCode::read_coils, 200, 25)), "81 09");
    EXPECT_EQ(ac20.send(codec::write_multiple_registers(139, Words(21, 0x8000))), "90 09");
    EXPECT_EQ(ac20.send(codec::write_multiple_coils(200, Words(25, 0))), "8F 09");
}

TEST(SimulatedAc20, UnimplementedWordsReadAs8000h_Fc3And4) {
    Simulated ac20("ac20", Model::profile_only);
    const Words words = ac20.read(115, 6);  // 116-118 are holes
    ASSERT_EQ(words.size(), 6U);
    EXPECT_EQ(words[1], 0x8000);
    EXPECT_EQ(words[3], 0x8000);
    EXPECT_EQ(words[5], 50);
    EXPECT_EQ(ac20.read(115, 6, FunctionCode::read_input_registers), words);  // FC4 reads the same words
}

TEST(SimulatedAc20, Written8000hIsDontCare_Fc6AndFc16) {
    Simulated ac20("ac20", Model::profile_only);
    EXPECT_EQ(ac20.send(codec::write_multiple_registers(139, {10, 20, 30})), echo_of(codec::write_multiple_registers(139, {10, 20, 30})));
    const auto block = codec::write_multiple_registers(139, {0x8000, 21, 0x8000});
    EXPECT_EQ(ac20.send(block), echo_of(block));
    EXPECT_EQ(ac20.read(139, 3), (Words{10, 21, 30}));
    EXPECT_EQ(ac20.send(codec::write_single_register(140, 0x8000)), echo_of(codec::write_single_register(140, 0x8000)));
    EXPECT_EQ(ac20.word(140), 21);
}

TEST(SimulatedAc20, ReadOnlyDataIsIgnoredInWrites_Fc15AndFc16) {
    Simulated ac20("ac20", Model::profile_only);
    const auto write = codec::write_single_register(120, 7);
    EXPECT_EQ(ac20.send(write), echo_of(write));
    EXPECT_EQ(ac20.word(120), 50);
    const auto bits = codec::write_multiple_coils(210, {1});  // change flag 210 is read-only
    EXPECT_EQ(ac20.send(bits), echo_of(bits));
    EXPECT_EQ(ac20.read(210, 1, FunctionCode::read_coils), Words{0});
}

TEST(SimulatedAc20, Fc16AbortsAtTheFirstErrorKeepingEarlierWords_Fc16) {
    Simulated ac20("ac20", Model::profile_only);
    ASSERT_EQ(ac20.send(codec::write_multiple_registers(1011, {0, 100})), echo_of(codec::write_multiple_registers(1011, {0, 100})));
    // SP2 = 50 is in rL..rH and written; SP3 = 500 is above rH: error 3, SP4 not reached.
    EXPECT_EQ(ac20.send(codec::write_multiple_registers(139, {50, 500, 60})), "90 03");
    EXPECT_EQ(ac20.read(139, 3), (Words{50, 0, 0}));
}

TEST(SimulatedAc20, WriteToAnUnlistedWordGetsError2_ErrorReply) {
    Simulated ac20("ac20", Model::profile_only);
    EXPECT_EQ(ac20.send(codec::write_single_register(116, 1)), "86 02");
}

TEST(SimulatedAc20, BroadcastWritesAreExecutedReadsIgnored_Note1) {
    Simulated ac20("ac20", Model::profile_only);
    EXPECT_EQ(ac20.send(codec::write_single_coil(218, true), true), "silence");
    EXPECT_EQ(ac20.read(218, 1, FunctionCode::read_coils), Words{1});
    EXPECT_EQ(ac20.send(codec::read_request(FunctionCode::read_holding_registers, 120, 1), true), "silence");
}

}  // namespace
}  // namespace loopwire::device
