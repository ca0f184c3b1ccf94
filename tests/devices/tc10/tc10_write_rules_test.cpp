// Rules that tie TC10 words together, through the wire (tc10-modbus-im05c01e81-03.ru.txt): dP per
// input type (§5.3.1 #2), ranges bounded by other parameters (§5.1 6A–9A, 16A, 29A; §5.3.2
// #15/#16; §5.3.3–5.3.5; §5.3.8; §5.3.12 CAI), ranges in display counts (§4.1) and the
// quick-configuration codes (§5.1 22A–25A). A refused write answers exception 3 and leaves
// memory unchanged (§4.4 B.2). Each test names its section.
#include <gtest/gtest.h>

#include <cstdint>

#include "codec/pdu.hpp"
#include "devices/tc10/tc10_test_support.hpp"

namespace loopwire::device {
namespace {

using namespace testing;
using namespace tc10_testing;

constexpr std::uint16_t input_type = 640, decimal_point_mirror = 10241;
constexpr std::uint16_t ao1_low = 653, ao1_high = 654, retransmission = 29;
constexpr std::uint16_t al2_low = 676, al2_high = 677, al2 = 678, al3_type = 682;
constexpr std::uint16_t al3_low = 684, al3_high = 685, al3 = 686;
constexpr std::uint16_t sp_low = 715, sp_high = 716, sp_2 = 718, set_point_var = 6;
constexpr std::uint16_t calibration_low = 777, calibration_high = 779;
constexpr std::uint16_t temp_code_1 = 22, temp_code_2 = 23, final_code_1 = 24, final_code_2 = 25;
constexpr std::uint16_t thermocouple_j = 0, rtd_pt100 = 7, current_4_20 = 12;

// --- §5.3.1 #2 dP: "0 ... 3" for linear inputs, "0/1" for the others -------------------------

TEST(Tc10Rules, DecimalPointZeroToThreeOnlyForLinearInputs_Section5_3_1_2) {
    Simulated tc10("tc10");
    ASSERT_EQ(tc10.word(input_type), thermocouple_j);
    EXPECT_EQ(tc10.write(decimal_point, 2), "86 03");
    EXPECT_EQ(tc10.write(decimal_point_mirror, 3), "86 03");  // the 10240… mirror is the same word
    EXPECT_EQ(tc10.word(decimal_point), 0);
    set(tc10, decimal_point, 1);
    set(tc10, input_type, current_4_20);  // 12 = 4.20, a linear input
    set(tc10, decimal_point, 3);
    EXPECT_EQ(tc10.word(decimals), 3);  // 2A follows
}

TEST(Tc10Rules, DecimalPointCheckedAgainstTheInputTypeOfTheSameRequest_Section5_3_1_2And4_4B2) {
    Simulated tc10("tc10");
    // FC16 640…641: SEnS then dP. A linear input written first makes dP 3 legal…
    const auto linear = codec::write_multiple_registers(input_type, {current_4_20, 3});
    EXPECT_EQ(tc10.send(linear), echo_of(linear));
    EXPECT_EQ(tc10.word(decimal_point), 3);
    // …an RTD does not, and then neither word changes.
    EXPECT_EQ(tc10.send(codec::write_multiple_registers(input_type, {rtd_pt100, 2})), "90 03");
    EXPECT_EQ(tc10.word(input_type), current_4_20);
    EXPECT_EQ(tc10.word(decimal_point), 3);
}

// The manual leaves open what a non-linear input does to dP 2 or 3: the simulator lowers it to 1.
TEST(Tc10Rules, NonLinearInputTypeLowersTheDecimalPointToOne_Section5_3_1_2) {
    Simulated tc10("tc10");
    set(tc10, input_type, current_4_20);
    set(tc10, decimal_point, 2);
    set(tc10, input_type, rtd_pt100);
    EXPECT_EQ(tc10.word(decimal_point), 1);
    EXPECT_EQ(tc10.word(decimals), 1);
    set(tc10, decimal_point, 0);
    set(tc10, input_type, current_4_20);
    EXPECT_EQ(tc10.word(decimal_point), 0);  // a linear input keeps what it has
}

// --- §4.1 ranges printed in display counts follow dP ------------------------------------------

// §5.3.7 #62 Pb "1 ... 9999 (ед. измерения)", dP: at dP = 1 the band ends at 999.9 (raw 9999);
// 1000.0 (raw 10000) is out of range even though 1000.0 < 9999 engineering units.
TEST(Tc10Rules, RangesInDisplayCountsHoldAtEveryDecimalPoint_Section4_1And5_3_7_62) {
    Simulated tc10("tc10");
    set(tc10, decimal_point, 1);
    EXPECT_EQ(tc10.write(proportional_band, 10000), "86 03");
    EXPECT_EQ(tc10.word(proportional_band), 20);
    set(tc10, proportional_band, 9999);
    set(tc10, input_type, current_4_20);
    set(tc10, decimal_point, 3);
    // §5.3.3 #33 HAL1 "1 ... 9999": raw 1 = 0.001 is the smallest hysteresis at dP = 3.
    EXPECT_EQ(tc10.write(al1_hysteresis, 0), "86 03");
    set(tc10, al1_hysteresis, 1);
    // §5.3.8 #77 SP.LL "-1999 ... SP.HL": raw -2000 is below -1.999.
    EXPECT_EQ(tc10.write(sp_low, raw(-2000)), "86 03");
    set(tc10, sp_low, -1999);
}

// --- §5.3.8 #77–82, §5.1 6A–9A, 16A: "SP.LL ... SP.HL" ----------------------------------------

TEST(Tc10Rules, SetPointsStayWithinSpLlAndSpHl_Section5_3_8_77To82And5_1_6A_16A) {
    Simulated tc10("tc10");
    set(tc10, sp_low, 100);
    set(tc10, sp_high, 200);
    EXPECT_EQ(tc10.write(sp_low, 201), "86 03");  // #77 "-1999 ... SP.HL"
    EXPECT_EQ(tc10.write(sp_high, 99), "86 03");  // #78 "SP.LL ... 9999"
    EXPECT_EQ(tc10.write(set_point, 201), "86 03");
    EXPECT_EQ(tc10.write(sp_2, 99), "86 03");
    EXPECT_EQ(tc10.write(set_point_var, 250), "86 03");
    EXPECT_EQ(tc10.write(remote_sp, 99), "86 03");
    set(tc10, set_point, 150);
    EXPECT_EQ(tc10.word(set_point_var), 150);
}

// The manual does not say what a limit moved past a set point does to it: the simulator brings
// the set point to the new limit, so "SP.LL ... SP.HL" always holds.
TEST(Tc10Rules, MovingALimitPastTheSetPointsBringsThemAlong_Section5_3_8_77_78) {
    Simulated tc10("tc10");
    set(tc10, set_point, 150);
    set(tc10, sp_2, 20);
    set(tc10, sp_high, 120);
    EXPECT_EQ(tc10.word(set_point), 120);
    EXPECT_EQ(tc10.word(set_point_var), 120);  // 6A is SP as well
    EXPECT_EQ(tc10.word(sp_2), 20);
    set(tc10, sp_low, 50);
    EXPECT_EQ(tc10.word(sp_2), 50);
    EXPECT_EQ(tc10.word(set_point), 120);
}

// --- §5.3.3–5.3.5: "AL1L ... AL1H" and the limits' own "-1999 ... AL1H" / "AL1L ... 9999" -------

TEST(Tc10Rules, AlarmThresholdsStayWithinTheirLimits_Section5_3_3_30To32And5_3_4_38To40) {
    Simulated tc10("tc10");
    set(tc10, al1_low, 0);
    set(tc10, al1_high, 100);
    EXPECT_EQ(tc10.write(al1_low, 101), "86 03");
    EXPECT_EQ(tc10.write(al1_high, raw(-1)), "86 03");
    EXPECT_EQ(tc10.write(al1, 101), "86 03");
    set(tc10, al1, 80);
    set(tc10, al1_high, 60);  // the threshold follows its limit (simulator's choice)
    EXPECT_EQ(tc10.word(al1), 60);
    set(tc10, al2_low, 10);
    set(tc10, al2_high, 20);
    EXPECT_EQ(tc10.write(al2, 21), "86 03");
    EXPECT_EQ(tc10.write(al2, 9), "86 03");
    set(tc10, al2, 15);
}

// §5.3.5 #46–48 print AL1H / AL1L for AL3's limits (copied from AL1); AL3 keeps its own
// AL3L…AL3H (profiles/NOTES.md), so AL1's limits do not bound it.
TEST(Tc10Rules, Alarm3UsesItsOwnLimits_Section5_3_5_46To48) {
    Simulated tc10("tc10");
    set(tc10, al1_low, 0);
    set(tc10, al1_high, 100);
    set(tc10, al3_low, raw(-50));
    set(tc10, al3_high, 500);
    set(tc10, al3, 400);
    EXPECT_EQ(tc10.write(al3, 501), "86 03");
    EXPECT_EQ(tc10.write(al3_low, 501), "86 03");
}

// --- §5.3.2 #15/#16 "-1999 ... Ao1H" / "Ao1L ... 9999", §5.1 29A "Ao1L ... Ao1H" ---------------

TEST(Tc10Rules, RetransmissionValueWithinAo1LAndAo1H_Section5_3_2_15_16And5_1_29A) {
    Simulated tc10("tc10");
    set(tc10, ao1_low, 0);
    set(tc10, ao1_high, 500);
    EXPECT_EQ(tc10.write(ao1_low, 501), "86 03");
    EXPECT_EQ(tc10.write(retransmission, 501), "86 03");
    EXPECT_EQ(tc10.write(retransmission, raw(-1)), "86 03");
    set(tc10, retransmission, 400);
    set(tc10, ao1_high, 300);
    EXPECT_EQ(tc10.word(retransmission), 300);
}

// --- §5.3.12 (CAI) #139 "-1999 ... (A.H.P - 10)", #141 "(A.L.P + 10) ... 9999" ------------------

TEST(Tc10Rules, CalibrationPointsStayTenCountsApart_Section5_3_12_139And141) {
    Simulated tc10("tc10");
    set(tc10, calibration_high, 100);
    EXPECT_EQ(tc10.write(calibration_low, 91), "86 03");
    set(tc10, calibration_low, 90);
    EXPECT_EQ(tc10.write(calibration_high, 99), "86 03");
    EXPECT_EQ(tc10.word(calibration_high), 100);
    set(tc10, calibration_high, 100);
}

// --- §5.1 22A–25A quick configuration ----------------------------------------------------------

TEST(Tc10Rules, QuickConfigurationWordsReadNotEnteredAndNotProgrammed_Section5_1_22A_To_25A) {
    Simulated tc10("tc10");
    EXPECT_EQ(tc10.word(temp_code_1), 10000);  // "10000 = Временное значение не вставлено"
    EXPECT_EQ(tc10.word(temp_code_2), 10000);
    EXPECT_EQ(tc10.word(final_code_1), 0xFFFF);  // "-1 = Код не запрограммирован"
    EXPECT_EQ(tc10.word(final_code_2), 0xFFFF);
    EXPECT_EQ(tc10.write(final_code_1, 1205), "86 02");  // 24A/25A are read-only
}

TEST(Tc10Rules, QuickConfigurationDigitsWithinTheirRanges_Section5_1_22A_23A) {
    Simulated tc10("tc10");
    EXPECT_EQ(tc10.write(temp_code_1, 2600), "86 03");  // AA = 26 > 25
    EXPECT_EQ(tc10.write(temp_code_1, 1222), "86 03");  // BB = 22 > 21
    EXPECT_EQ(tc10.write(temp_code_2, 1235), "86 03");  // F = 5 > 4
    EXPECT_EQ(tc10.write(temp_code_2, raw(-1)), "86 03");
    EXPECT_EQ(tc10.word(temp_code_1), 10000);
    set(tc10, temp_code_1, 2521);
    EXPECT_EQ(tc10.word(temp_code_1), 2521);  // entered, waiting for the second code
    EXPECT_EQ(tc10.word(final_code_1), 0xFFFF);
}

// "Запрограммированные коды будут активированы только после правильного задания обеих субкодов.
// Порядок не имеет значения." — active once both are entered, in either order.
TEST(Tc10Rules, QuickConfigurationActiveOnlyOnceBothCodesAreEnteredInEitherOrder_Section5_1_22A_23A) {
    Simulated tc10("tc10");
    set(tc10, temp_code_2, 2130);  // AL1t 2, AL2t 1, AL3t 3, services 0
    EXPECT_EQ(tc10.word(final_code_2), 0xFFFF);
    EXPECT_EQ(tc10.word(al1_type), 0);
    set(tc10, temp_code_1, 1205);  // SEnS 12 (4.20), control 05
    EXPECT_EQ(tc10.word(final_code_1), 1205);
    EXPECT_EQ(tc10.word(final_code_2), 2130);
    EXPECT_EQ(tc10.word(temp_code_1), 10000);
    EXPECT_EQ(tc10.word(temp_code_2), 10000);
    EXPECT_EQ(tc10.word(input_type), current_4_20);
    EXPECT_EQ(tc10.word(al1_type), 2);
    EXPECT_EQ(tc10.word(al2_type), 1);
    EXPECT_EQ(tc10.word(al3_type), 3);
    // The other order, and a decimal point the new input does not offer drops to 1.
    set(tc10, decimal_point, 3);
    set(tc10, temp_code_1, 700);  // SEnS 7 = Pt100
    set(tc10, temp_code_2, 4);
    EXPECT_EQ(tc10.word(final_code_1), 700);
    EXPECT_EQ(tc10.word(input_type), rtd_pt100);
    EXPECT_EQ(tc10.word(decimal_point), 1);
    EXPECT_EQ(tc10.word(al1_type), 0);
}

TEST(Tc10Rules, QuickConfigurationCodeClearedBy10000IsNoLongerEntered_Section5_1_22A) {
    Simulated tc10("tc10");
    set(tc10, temp_code_1, 1205);
    set(tc10, temp_code_1, 10000);
    set(tc10, temp_code_2, 2130);
    EXPECT_EQ(tc10.word(final_code_1), 0xFFFF);
    EXPECT_EQ(tc10.word(input_type), thermocouple_j);
    // Input codes 17…25 are in 22A's range but §5.3.1 lists no such input: SEnS stays.
    set(tc10, temp_code_1, 2000);
    EXPECT_EQ(tc10.word(final_code_1), 2000);
    EXPECT_EQ(tc10.word(input_type), thermocouple_j);
}

}  // namespace
}  // namespace loopwire::device
