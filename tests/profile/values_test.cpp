// Raw words <-> engineering values on the real profiles: decimals read from another word,
// special values before scaling, enum labels, named bits, and writes refused with the limit.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "profile/value_format.hpp"
#include "profile/values.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using ::testing::HasSubstr;
using testing::builtin;
using testing::parameter;

double number_of(const Result<EngineeringValue>& decoded) {
    EXPECT_TRUE(decoded.ok()) << (decoded.ok() ? "" : decoded.error().message);
    if (!decoded.ok()) return -1e9;
    EXPECT_EQ(decoded->status, "ok");
    const double* number = std::get_if<double>(&decoded->value);
    EXPECT_NE(number, nullptr) << "not a number";
    return number == nullptr ? -1e9 : *number;
}

std::string label_of(const Result<EngineeringValue>& decoded) {
    EXPECT_TRUE(decoded.ok()) << (decoded.ok() ? "" : decoded.error().message);
    if (!decoded.ok()) return {};
    const std::string* label = std::get_if<std::string>(&decoded->value);
    EXPECT_NE(label, nullptr) << "not a label";
    return label == nullptr ? std::string() : *label;
}

std::string state_of(const Result<EngineeringValue>& decoded) {
    EXPECT_TRUE(decoded.ok()) << (decoded.ok() ? "" : decoded.error().message);
    if (!decoded.ok()) return {};
    EXPECT_TRUE(std::holds_alternative<std::monostate>(decoded->value)) << "a special state has no value";
    return decoded->status;
}

std::string error_of(const Result<std::uint16_t>& encoded) {
    EXPECT_FALSE(encoded.ok()) << "accepted as raw " << (encoded.ok() ? *encoded : 0);
    if (encoded.ok()) return {};
    EXPECT_EQ(encoded.error().kind, ErrorKind::usage);
    return encoded.error().message;
}

std::uint16_t raw_from(const Result<std::uint16_t>& encoded) {
    EXPECT_TRUE(encoded.ok()) << (encoded.ok() ? "" : encoded.error().message);
    return encoded.ok() ? *encoded : 0xDEAD;
}

std::uint16_t word(int value) { return static_cast<std::uint16_t>(value & 0xFFFF); }

// ---- AC20: decimals from word 300, 8000h and 7FFFh, 300xx measurement codes ----------------

TEST(Ac20Values, SetPointTakesItsDecimalsFromWord300) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const Parameter& decimals = parameter(*ac20, "primary_variable_decimals");
    EXPECT_EQ(decimals.address, 300);
    const Parameter& sp = parameter(*ac20, "main_set_point");
    EXPECT_DOUBLE_EQ(number_of(decode_value(sp, 1370, {{"primary_variable_decimals", 1}})), 137.0);
    EXPECT_DOUBLE_EQ(number_of(decode_value(sp, 1370, {{"primary_variable_decimals", 2}})), 13.70);
    EXPECT_DOUBLE_EQ(number_of(decode_value(sp, word(-25), {{"primary_variable_decimals", 0}})), -25.0);
    EXPECT_EQ(dependencies_of(sp),
              (std::vector<std::string>{"primary_variable_decimals", "primary_variable_selection", "temperature_input_type",
                                                  "set_point_low_limit", "set_point_high_limit"}));
}

// The text keeps the decimals the device gave the value ("0.85 %C", not "1 %C"):
// 100 counts at word 300's two decimals read "1.00", at none "100"; a value made by hand shows
// what it holds.
TEST(Ac20Values, TextKeepsTheDecimalsTheDeviceGave) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const Parameter& sp = parameter(*ac20, "main_set_point");
    const auto two = decode_value(sp, 100, {{"primary_variable_decimals", 2}});
    ASSERT_TRUE(two.ok());
    EXPECT_EQ(two->decimals, 2);
    EXPECT_EQ(value_text(sp, *two), "1.00");
    EXPECT_EQ(value_text(sp, *decode_value(sp, 85, {{"primary_variable_decimals", 2}})), "0.85");
    EXPECT_EQ(value_text(sp, *decode_value(sp, 100, {{"primary_variable_decimals", 0}})), "100");
    EXPECT_EQ(value_text(sp, *decode_value(sp, word(-25), {{"primary_variable_decimals", 1}})), "-2.5");
    EXPECT_EQ(value_text(sp, EngineeringValue{1.5, "ok", 0, ""}), "1.5");
}

TEST(Ac20Values, MissingDecimalsNameTheWordToReadFirst) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const auto decoded = decode_value(parameter(*ac20, "main_set_point"), 1370, {});
    ASSERT_FALSE(decoded.ok());
    EXPECT_THAT(decoded.error().message, HasSubstr("read primary_variable_decimals first"));
    // Word 300 reading 8000h (not available in configuration mode) gives no decimals either.
    const auto unavailable = decimals_of(parameter(*ac20, "main_set_point"), {{"primary_variable_decimals", 0x8000}});
    ASSERT_FALSE(unavailable.ok());
    EXPECT_THAT(unavailable.error().message, HasSubstr("32768"));
}

TEST(Ac20Values, Word8000hReadsAsNotAvailableOnEveryWord) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    EXPECT_EQ(state_of(decode_value(parameter(*ac20, "main_set_point"), 0x8000, {})), "not-available");
    EXPECT_EQ(state_of(decode_value(parameter(*ac20, "serial_interface_protocol"), 0x8000, {})), "not-available");
    EXPECT_EQ(state_of(decode_value(parameter(*ac20, "probe_millivolts"), 0x8000, {})), "not-available");
}

TEST(Ac20Values, SpecialsAreCheckedBeforeScaling) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    EXPECT_EQ(state_of(decode_value(parameter(*ac20, "probe_millivolts"), 30004, {})), "under-range");
    EXPECT_EQ(state_of(decode_value(parameter(*ac20, "probe_temperature"), 30002, {})), "input-open");
    EXPECT_DOUBLE_EQ(number_of(decode_value(parameter(*ac20, "probe_millivolts"), 30003, {})), 30003.0);
    EXPECT_EQ(state_of(decode_value(parameter(*ac20, "integral_time"), 0x7FFF, {})), "excluded");
    EXPECT_EQ(state_of(decode_value(parameter(*ac20, "set_point_rate_positive"), 0x7FFF, {})), "step");
}

TEST(Ac20Values, SpecialStateNamesAreAcceptedOnWrite) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const RawValues known{{"primary_variable_decimals", 1}};
    EXPECT_EQ(raw_from(encode_value(parameter(*ac20, "main_set_point"), "dont-care", known)), 0x8000);
    EXPECT_EQ(raw_from(encode_value(parameter(*ac20, "integral_time"), "excluded", known)), 0x7FFF);
    EXPECT_EQ(raw_from(encode_value(parameter(*ac20, "main_output_max_rate_of_rise"), "No-Limit", known)), 0x7FFF);
}

TEST(Ac20Values, SetPointIsBoundedByRlAndRh) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const Parameter& sp = parameter(*ac20, "main_set_point");
    const RawValues known{{"primary_variable_decimals", 1}, {"set_point_low_limit", 0}, {"set_point_high_limit", 15000}};
    EXPECT_EQ(raw_from(encode_value(sp, "137.0", known)), 1370);
    EXPECT_EQ(raw_from(encode_value(sp, "1500", known)), 15000);
    EXPECT_THAT(error_of(encode_value(sp, "1500.1", known)),
                HasSubstr("main_set_point 1500.1 is above its upper limit set_point_high_limit = 1500.0"));
    EXPECT_THAT(error_of(encode_value(sp, "-0.1", known)),
                HasSubstr("main_set_point -0.1 is below its lower limit set_point_low_limit = 0.0"));
    EXPECT_THAT(error_of(encode_value(sp, "137.05", known)),
                HasSubstr("main_set_point 137.05 has 2 decimals, but main_set_point takes 1"));
}

TEST(Ac20Values, LockWordsShowStatesButTakeCombinations) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const Parameter& code = parameter(*ac20, "configuration_mode_code");
    EXPECT_EQ(label_of(decode_value(code, 2, {})), "locked_by_software_key");
    EXPECT_EQ(raw_from(encode_value(code, "100", {})), 100);
    EXPECT_THAT(error_of(encode_value(code, "251", {})), HasSubstr("configuration_mode_code 251 is above its upper limit 250"));
}

TEST(Ac20Values, BitsAreNumbersOrTheirLabels) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    EXPECT_EQ(label_of(decode_value(parameter(*ac20, "local_remote"), 1, {})), "remote");
    EXPECT_EQ(raw_from(encode_value(parameter(*ac20, "local_remote"), "REMOTE", {})), 1);
    EXPECT_EQ(raw_from(encode_value(parameter(*ac20, "local_remote"), "0", {})), 0);
    EXPECT_DOUBLE_EQ(number_of(decode_value(parameter(*ac20, "start_probe_test"), 1, {})), 1.0);
    EXPECT_EQ(raw_from(encode_value(parameter(*ac20, "start_probe_test"), "on", {})), 1);
    EXPECT_FALSE(decode_value(parameter(*ac20, "start_probe_test"), 2, {}).ok());
    EXPECT_THAT(error_of(encode_value(parameter(*ac20, "auxiliary_input_1"), "closed", {})),
                HasSubstr("auxiliary_input_1 is read-only"));
}

// ---- TC10: set point bounded by SPLL/SPLH, 10000-range measurement errors --------------------

TEST(Tc10Values, SetPointIsBoundedBySpllAndSplh) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& sp = parameter(*tc10, "set_point");
    const RawValues known{{"decimal_point", 1}, {"set_point_low_limit", word(-500)}, {"set_point_high_limit", 12000}};
    EXPECT_EQ(raw_from(encode_value(sp, "1200.0", known)), 12000);
    EXPECT_EQ(raw_from(encode_value(sp, "-50", known)), word(-500));
    EXPECT_EQ(raw_from(encode_value(sp, " 250.5 ", known)), 2505);
    EXPECT_THAT(error_of(encode_value(sp, "1500", known)),
                HasSubstr("set_point 1500 is above its upper limit set_point_high_limit = 1200.0"));
    EXPECT_THAT(error_of(encode_value(sp, "-50.1", known)),
                HasSubstr("set_point -50.1 is below its lower limit set_point_low_limit = -50.0"));
    EXPECT_THAT(error_of(encode_value(sp, "250.55", known)), HasSubstr("has 2 decimals"));
    EXPECT_THAT(error_of(encode_value(sp, "2.5e2", known)), HasSubstr("\"2.5e2\" is not a number"));
    EXPECT_THAT(error_of(encode_value(sp, "", known)), HasSubstr("set_point: no value given"));
}

// The limits every front shows are the numbers a write is checked against: SP between the
// device's SP.LL and SP.HL at its decimal point, display counts scaled, nothing when unknown.
TEST(Tc10Values, LimitsAreTheNumbersAWriteIsCheckedAgainst) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& sp = parameter(*tc10, "set_point");
    const RawValues known{{"decimal_point", 1}, {"set_point_low_limit", word(-500)}, {"set_point_high_limit", 12000}};
    EXPECT_EQ(limits_of(sp, known), (ValueLimits{-50.0, 1200.0}));
    EXPECT_EQ(limits_of(sp, {{"decimal_point", 1}, {"set_point_low_limit", 0}}), (ValueLimits{0.0, std::nullopt}));
    EXPECT_EQ(limits_of(sp, {}), ValueLimits{}) << "neither the bounds nor the decimals are known";
    const Parameter& band = parameter(*tc10, "proportional_band");
    EXPECT_EQ(limits_of(band, {{"decimal_point", 1}}), (ValueLimits{0.1, 999.9}));
    EXPECT_EQ(limits_of(band, {}), ValueLimits{}) << "counts without the decimal point are no number";
    EXPECT_EQ(limits_of(parameter(*tc10, "control_state"), {}), (ValueLimits{0.0, 2.0}))
        << "an enumeration's limits are its range of codes, as a code written as a number is checked";
    EXPECT_EQ(limits_of(parameter(*tc10, "alarm_status"), {}), ValueLimits{}) << "bits have no limits";
}

TEST(Tc10Values, UnknownBoundIsReportedAsSuch) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& sp = parameter(*tc10, "set_point");
    EXPECT_THAT(error_of(encode_value(sp, "100", {{"decimal_point", 1}, {"set_point_low_limit", 0}})),
                HasSubstr("set_point: its upper limit set_point_high_limit is not known; read set_point_high_limit first"));
    EXPECT_EQ(dependencies_of(sp),
              (std::vector<std::string>{"decimal_point", "temperature_unit", "set_point_low_limit", "set_point_high_limit"}));
    // A bound the parameter does not describe (built by hand, not loaded) cannot be decoded:
    // said, not guessed.
    Parameter by_hand = sp;
    by_hand.bound_sources.clear();
    EXPECT_THAT(error_of(encode_value(by_hand, "100", {{"decimal_point", 1}, {"set_point_low_limit", 0}})),
                HasSubstr("set_point: its lower limit set_point_low_limit is not described"));
}

// A bound is decoded with its own type and decimals, as loaded from the bounding entry.
TEST(Tc10Values, BoundsAreDecodedWithTheirOwnScaling) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    Parameter sp = parameter(*tc10, "set_point");
    ASSERT_EQ(sp.bound_sources.size(), 2u);
    const BoundSource& high = sp.bound_sources.at("set_point_high_limit");
    EXPECT_EQ(high.type, ValueType::int16);
    EXPECT_EQ(std::get<std::string>(high.decimals), "decimal_point");
    // Were the high limit stored with two fixed decimals, 12000 would mean 120.00.
    sp.bound_sources.at("set_point_high_limit").decimals = 2;
    const RawValues known{{"decimal_point", 1}, {"set_point_low_limit", 0}, {"set_point_high_limit", 12000}};
    EXPECT_THAT(error_of(encode_value(sp, "120.1", known)),
                HasSubstr("set_point 120.1 is above its upper limit set_point_high_limit = 120.00"));
    EXPECT_EQ(raw_from(encode_value(sp, "120.0", known)), 1200);
}

TEST(Tc10Values, MeasuredValueErrorsAreSpecialStates) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& rv = parameter(*tc10, "measured_value");
    const RawValues known{{"decimal_point", 1}};
    EXPECT_EQ(state_of(decode_value(rv, 10000, known)), "out-of-range");
    EXPECT_EQ(state_of(decode_value(rv, 10001, known)), "adc-overflow");
    EXPECT_EQ(state_of(decode_value(rv, 10003, known)), "not-available");
    EXPECT_DOUBLE_EQ(number_of(decode_value(rv, 10002, known)), 1000.2);  // not assigned by the manual
    EXPECT_DOUBLE_EQ(number_of(decode_value(rv, word(-200), known)), -20.0);
    EXPECT_THAT(error_of(encode_value(rv, "20", known)), HasSubstr("measured_value is read-only"));
}

TEST(Tc10Values, ZeroMeansOffForNumericParameters) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& filter = parameter(*tc10, "input_filter");
    EXPECT_EQ(state_of(decode_value(filter, 0, {})), "off");
    EXPECT_DOUBLE_EQ(number_of(decode_value(filter, 15, {})), 1.5);
    EXPECT_EQ(raw_from(encode_value(filter, "off", {})), 0);
    EXPECT_THAT(error_of(encode_value(filter, "20.1", {})), HasSubstr("input_filter 20.1 is above its upper limit 20.0 s"));
}

// §4.1: dP values are fixed-point with a programmable decimal point; §5.3.7 #62 Pb "1 ... 9999
// (ед. измерения)" is printed in display counts ("range": {"counts": true}), so at dP = 1 the
// band ends at 999.9 and 1000.0 (raw 10000) is refused, naming the limit in engineering units.
TEST(Tc10Values, RangesInDisplayCountsFollowTheDecimalPoint_Section4_1And5_3_7_62) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& band = parameter(*tc10, "proportional_band");
    EXPECT_TRUE(band.range_in_counts);
    const RawValues dp0{{"decimal_point", 0}, {"temperature_unit", 0}};
    const RawValues dp1{{"decimal_point", 1}, {"temperature_unit", 0}};
    const RawValues dp3{{"decimal_point", 3}, {"temperature_unit", 0}};
    EXPECT_EQ(raw_from(encode_value(band, "9999", dp0)), 9999);
    EXPECT_EQ(raw_from(encode_value(band, "999.9", dp1)), 9999);
    EXPECT_THAT(error_of(encode_value(band, "1000.0", dp1)),
                HasSubstr("proportional_band 1000.0 is above its upper limit 999.9 °C (9999 counts at 1 decimal)"));
    EXPECT_THAT(error_of(encode_value(band, "0.0", dp1)),
                HasSubstr("proportional_band 0.0 is below its lower limit 0.1 °C (1 counts at 1 decimal)"));
    EXPECT_THAT(error_of(encode_value(band, "10", dp3)), HasSubstr("above its upper limit 9.999 °C (9999 counts at 3 decimals)"));
    // A bound that names another parameter is that parameter's value, not a count.
    const Parameter& low = parameter(*tc10, "set_point_low_limit");
    const RawValues limits{{"decimal_point", 1}, {"temperature_unit", 0}, {"set_point_high_limit", 5000}};
    EXPECT_EQ(raw_from(encode_value(low, "-199.9", limits)), word(-1999));
    EXPECT_THAT(error_of(encode_value(low, "-200.0", limits)), HasSubstr("below its lower limit -199.9 °C (-1999 counts at 1 decimal)"));
    EXPECT_THAT(error_of(encode_value(low, "500.1", limits)), HasSubstr("above its upper limit set_point_high_limit = 500.0"));
    // raw_in_range (the simulators' check) agrees: raw 10000 at dP = 1 is out, 9999 in.
    EXPECT_FALSE(raw_in_range(band, 10000, dp1));
    EXPECT_TRUE(raw_in_range(band, 9999, dp1));
}

// ramp/soak §7: PV "-1999~9999" and HYS1/HYS2 "0~1000" follow DP (0x004B) and are printed in counts.
TEST(RampSoakValues, RangesInDisplayCountsFollowDp_Section7) {
    const auto rampsoak = builtin("rampsoak");
    ASSERT_TRUE(rampsoak);
    const Parameter& hysteresis = parameter(*rampsoak, "out1_hysteresis");
    EXPECT_TRUE(hysteresis.range_in_counts);
    EXPECT_TRUE(parameter(*rampsoak, "process_value").range_in_counts);
    const RawValues known{{"decimal_point", 2}, {"unit", 0}};
    EXPECT_EQ(raw_from(encode_value(hysteresis, "10.00", known)), 1000);
    EXPECT_THAT(error_of(encode_value(hysteresis, "10.01", known)), HasSubstr("above its upper limit 10.00 °C (1000 counts at 2 decimals)"));
}

TEST(Tc10Values, StatusWordBitsAreNamed) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const auto decoded = decode_value(parameter(*tc10, "instrument_status"), (1u << 0) | (1u << 4) | (1u << 12), {});
    ASSERT_TRUE(decoded.ok());
    const auto& bits = std::get<std::map<std::string, bool>>(decoded->value);
    EXPECT_TRUE(bits.at("auto_mode"));
    EXPECT_TRUE(bits.at("autotune_active"));
    EXPECT_TRUE(bits.at("measurement_error"));
    EXPECT_FALSE(bits.at("manual_mode"));
    EXPECT_EQ(bits.size(), 10u);
    EXPECT_EQ(*format_value(parameter(*tc10, "instrument_status"), *decoded, {}), "auto_mode+autotune_active+measurement_error");
}

TEST(Tc10Values, WritableBitFieldsTakeNamesOrNumbersWithinRange) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& alarms = parameter(*tc10, "output_1_alarms");
    EXPECT_EQ(raw_from(encode_value(alarms, "alarm_1 + alarm_3", {})), 0b101);
    EXPECT_EQ(raw_from(encode_value(alarms, "none", {})), 0);
    EXPECT_EQ(raw_from(encode_value(alarms, "63", {})), 63);
    EXPECT_THAT(error_of(encode_value(alarms, "64", {})), HasSubstr("output_1_alarms 64 is above its upper limit 63"));
    EXPECT_THAT(error_of(encode_value(alarms, "alarm_9", {})), HasSubstr("\"alarm_9\" is not one of its bits"));
}

TEST(Tc10Values, EnumLabelsIncludingNegativeCodes) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& autotune = parameter(*tc10, "autotune_selection");
    EXPECT_EQ(label_of(decode_value(autotune, word(-4), {})), autotune.enum_labels.at(-4));
    EXPECT_EQ(label_of(decode_value(autotune, 7, {})), "EvoTune, manual start");
    EXPECT_EQ(raw_from(encode_value(autotune, "evotune, MANUAL start", {})), 7);
    EXPECT_EQ(raw_from(encode_value(autotune, "-3", {})), word(-3));
    EXPECT_THAT(error_of(encode_value(autotune, "9", {})), HasSubstr("\"9\" is not one of its values: -4 = "));
    // A code the profile gives no label keeps its number and says so.
    const auto unknown = decode_value(autotune, 9, {});
    ASSERT_TRUE(unknown.ok());
    EXPECT_EQ(unknown->status, "unknown-label");
    EXPECT_DOUBLE_EQ(std::get<double>(unknown->value), 9.0);
    const auto negative_unknown = decode_value(autotune, word(-9), {});
    ASSERT_TRUE(negative_unknown.ok());
    EXPECT_DOUBLE_EQ(std::get<double>(negative_unknown->value), -9.0);
}

TEST(Tc10Values, OutputPowerFillsASignedWordWithTwoDecimals) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& power = parameter(*tc10, "output_power");
    EXPECT_EQ(raw_from(encode_value(power, "-100.00", {})), word(-10000));
    EXPECT_EQ(raw_from(encode_value(power, "+12.5", {})), 1250);
    EXPECT_DOUBLE_EQ(number_of(decode_value(power, word(-10000), {})), -100.0);
    EXPECT_THAT(error_of(encode_value(power, "100.01", {})), HasSubstr("output_power 100.01 is above its upper limit 100.00 %"));
}

// ---- rampsoak: DP-scaled values, fixed decimals, OBIT -------------------------------------

TEST(RampsoakValues, ManualExamplesScaleByDp) {
    const auto rampsoak = builtin("rampsoak");
    ASSERT_TRUE(rampsoak);
    const RawValues known{{"decimal_point", 1}};
    EXPECT_DOUBLE_EQ(number_of(decode_value(parameter(*rampsoak, "process_value"), 0x03E8, known)), 100.0);
    EXPECT_DOUBLE_EQ(number_of(decode_value(parameter(*rampsoak, "set_value"), 0x0064, known)), 10.0);
    EXPECT_EQ(label_of(decode_value(parameter(*rampsoak, "decimal_point"), 1, {})), "000.0");
    const Parameter& limit = parameter(*rampsoak, "output_limit");
    EXPECT_EQ(raw_from(encode_value(limit, "100.0", {})), 0x03E8);  // §4.7.3: OUTL = 100.0 sent as 03E8H
    EXPECT_THAT(error_of(encode_value(limit, "100.1", {})), HasSubstr("output_limit 100.1 is above its upper limit 100.0 %"));
    EXPECT_THAT(error_of(encode_value(limit, "-1", {})), HasSubstr("output_limit -1 is below its lower limit 0.0 %"));
}

TEST(RampsoakValues, ObitNamesEveryBit) {
    const auto rampsoak = builtin("rampsoak");
    ASSERT_TRUE(rampsoak);
    const Parameter& obit = parameter(*rampsoak, "controller_status");
    EXPECT_EQ(obit.address, 0x88);
    const auto decoded = decode_value(obit, 0x8001, {});
    ASSERT_TRUE(decoded.ok());
    const auto& bits = std::get<std::map<std::string, bool>>(decoded->value);
    EXPECT_EQ(bits.size(), 16u);
    EXPECT_TRUE(bits.at("Message nnn2"));
    EXPECT_TRUE(bits.at("OUT1 LED"));
    EXPECT_FALSE(bits.at("MAN LED"));
}

// ---- the word itself ----------------------------------------------------------------------

Parameter writable_word(ValueType type, int decimals) {
    Parameter word_parameter;
    word_parameter.name = "test_word";
    word_parameter.type = type;
    word_parameter.decimals = decimals;
    word_parameter.writable = true;
    return word_parameter;
}

TEST(WordValues, SignedAndUnsignedLimitsAfterScaling) {
    const Parameter signed_word = writable_word(ValueType::int16, 1);
    EXPECT_EQ(raw_from(encode_value(signed_word, "3276.7", {})), 0x7FFF);
    EXPECT_EQ(raw_from(encode_value(signed_word, "-3276.8", {})), 0x8000);
    EXPECT_THAT(error_of(encode_value(signed_word, "3276.8", {})),
                HasSubstr("test_word 3276.8 does not fit its 16-bit word: with 1 decimals it holds -3276.8 .. 3276.7"));
    EXPECT_DOUBLE_EQ(number_of(decode_value(signed_word, 0x8000, {})), -3276.8);
    const Parameter unsigned_word = writable_word(ValueType::uint16, 0);
    EXPECT_EQ(raw_from(encode_value(unsigned_word, "65535", {})), 0xFFFF);
    EXPECT_DOUBLE_EQ(number_of(decode_value(unsigned_word, 0xFFFF, {})), 65535.0);
    EXPECT_THAT(error_of(encode_value(unsigned_word, "65536", {})), HasSubstr("does not fit"));
    EXPECT_THAT(error_of(encode_value(unsigned_word, "-1", {})), HasSubstr("does not fit"));
    EXPECT_THAT(error_of(encode_value(unsigned_word, "99999999999999999999", {})), HasSubstr("does not fit"));
}

TEST(WordValues, NumbersAreReadStrictly) {
    const Parameter value = writable_word(ValueType::int16, 2);
    EXPECT_EQ(raw_from(encode_value(value, "1.50", {})), 150);
    EXPECT_EQ(raw_from(encode_value(value, "1.500", {})), 150);  // trailing zeros change nothing
    EXPECT_EQ(raw_from(encode_value(value, "007", {})), 700);
    for (const char* bad : {"1.", ".5", "1,5", "0x10", "1e2", "--1", "1 2", "inf", "nan", "+"}) {
        EXPECT_THAT(error_of(encode_value(value, bad, {})), HasSubstr("is not a number")) << bad;
    }
    EXPECT_THAT(error_of(encode_value(value, "1.505", {})), HasSubstr("has 3 decimals"));
}

}  // namespace
}  // namespace loopwire::device
