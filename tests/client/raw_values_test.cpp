// Registers as the numbers they hold (client/raw_values.hpp), on IEEE 754 and two's complement
// bit patterns worked out by hand: 12.5f = 0x41480000 (sign 0, exponent 130, mantissa 1.5625),
// -3.25f = 0xC0500000, 0.1f = 0x3DCCCCCD, 1.5 = 0x3FF8000000000000, pi = 0x400921FB54442D18.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <optional>
#include <tuple>

#include "client/raw_values.hpp"

namespace loopwire::device {
namespace {

RawNumber one(std::vector<std::uint16_t> registers, RawType type, WordOrder order = WordOrder::big, bool swap = false) {
    return decode_value(registers, RawLayout{type, order, swap});
}

double as_double(const RawNumber& number) {
    EXPECT_TRUE(std::holds_alternative<double>(number));
    return std::holds_alternative<double>(number) ? std::get<double>(number) : std::nan("");
}

std::int64_t as_integer(const RawNumber& number) {
    EXPECT_TRUE(std::holds_alternative<std::int64_t>(number));
    return std::holds_alternative<std::int64_t>(number) ? std::get<std::int64_t>(number) : -999;
}

TEST(RawValues, Float32InEveryWordAndByteOrder) {
    EXPECT_EQ(as_double(one({0x4148, 0x0000}, RawType::float32)), 12.5);
    EXPECT_EQ(as_double(one({0x0000, 0x4148}, RawType::float32, WordOrder::little)), 12.5);
    EXPECT_EQ(as_double(one({0x4841, 0x0000}, RawType::float32, WordOrder::big, true)), 12.5);
    EXPECT_EQ(as_double(one({0x0000, 0x4841}, RawType::float32, WordOrder::little, true)), 12.5);
    EXPECT_EQ(as_double(one({0xC050, 0x0000}, RawType::float32)), -3.25);
    // The wrong order gives another number: the test can tell the orders apart.
    EXPECT_NE(as_double(one({0x4148, 0x0000}, RawType::float32, WordOrder::little)), 12.5);
}

TEST(RawValues, Float32IsTheNumberItsShortestDecimalSays) {
    const RawNumber tenth = one({0x3DCC, 0xCCCD}, RawType::float32);
    EXPECT_EQ(as_double(tenth), 0.1);  // not 0.100000001490116...
    EXPECT_EQ(number_text(tenth), "0.1");
    EXPECT_EQ(number_text(one({0x4148, 0x0000}, RawType::float32)), "12.5");
}

TEST(RawValues, Float32SpecialPatterns) {
    EXPECT_TRUE(std::isnan(as_double(one({0x7FC0, 0x0000}, RawType::float32))));
    EXPECT_EQ(as_double(one({0x7F80, 0x0000}, RawType::float32)), std::numeric_limits<double>::infinity());
    EXPECT_EQ(number_text(one({0xFF80, 0x0000}, RawType::float32)), "-inf");
    EXPECT_EQ(number_text(one({0x7FC0, 0x0000}, RawType::float32)), "nan");
    EXPECT_TRUE(std::signbit(as_double(one({0x8000, 0x0000}, RawType::float32))));  // -0
}

TEST(RawValues, Float64InBothWordOrders) {
    EXPECT_EQ(as_double(one({0x3FF8, 0, 0, 0}, RawType::float64)), 1.5);
    EXPECT_EQ(as_double(one({0x4009, 0x21FB, 0x5444, 0x2D18}, RawType::float64)), 3.141592653589793);
    EXPECT_EQ(as_double(one({0x2D18, 0x5444, 0x21FB, 0x4009}, RawType::float64, WordOrder::little)), 3.141592653589793);
    EXPECT_EQ(as_double(one({0x182D, 0x4454, 0xFB21, 0x0940}, RawType::float64, WordOrder::little, true)), 3.141592653589793);
    EXPECT_EQ(number_text(one({0x4009, 0x21FB, 0x5444, 0x2D18}, RawType::float64)), "3.141592653589793");
}

TEST(RawValues, IntegersSignedAndUnsigned) {
    EXPECT_EQ(as_integer(one({0xFFFF}, RawType::int16)), -1);
    EXPECT_EQ(as_integer(one({0xFFFF}, RawType::uint16)), 65535);
    EXPECT_EQ(as_integer(one({0x8000}, RawType::int16)), -32768);
    EXPECT_EQ(as_integer(one({0x3412}, RawType::uint16, WordOrder::big, true)), 0x1234);
    EXPECT_EQ(as_integer(one({0x075B, 0xCD15}, RawType::int32)), 123456789);
    EXPECT_EQ(as_integer(one({0xCD15, 0x075B}, RawType::int32, WordOrder::little)), 123456789);
    EXPECT_EQ(as_integer(one({0xFFFF, 0xFFFE}, RawType::int32)), -2);
    EXPECT_EQ(as_integer(one({0xFFFE, 0xFFFF}, RawType::int32, WordOrder::little)), -2);
    EXPECT_EQ(as_integer(one({0xFFFF, 0xFFFE}, RawType::uint32)), 4294967294);
    EXPECT_EQ(as_integer(one({0xEE6B, 0x2800}, RawType::uint32)), 4000000000);
    EXPECT_EQ(as_integer(one({0x8000, 0x0000}, RawType::int32)), -2147483648LL);
}

TEST(RawValues, ManyValuesNeedWholeOnes) {
    const std::vector<std::uint16_t> registers{0x4148, 0x0000, 0xC050, 0x0000};
    auto values = decode_values(registers, RawLayout{RawType::float32});
    ASSERT_TRUE(values) << values.error().message;
    ASSERT_EQ(values->size(), 2u);
    EXPECT_EQ(as_double((*values)[0]), 12.5);
    EXPECT_EQ(as_double((*values)[1]), -3.25);
    const std::vector<std::uint16_t> odd{0x4148, 0x0000, 0xC050};
    auto refused = decode_values(odd, RawLayout{RawType::int32});
    ASSERT_FALSE(refused);
    EXPECT_EQ(refused.error().kind, ErrorKind::usage);
    EXPECT_EQ(refused.error().message, "3 registers do not make whole int32 values: each takes 2");
    EXPECT_FALSE(decode_values(std::vector<std::uint16_t>{1, 2, 3, 4, 5}, RawLayout{RawType::float64}));
}

TEST(RawValues, TypeNamesAndTheirErrors) {
    for (auto type : {RawType::int16, RawType::uint16, RawType::int32, RawType::uint32, RawType::float32, RawType::float64}) {
        auto parsed = parse_raw_type(raw_type_name(type));
        ASSERT_TRUE(parsed);
        EXPECT_EQ(*parsed, type);
    }
    EXPECT_EQ(registers_per_value(RawType::int16), 1u);
    EXPECT_EQ(registers_per_value(RawType::float32), 2u);
    EXPECT_EQ(registers_per_value(RawType::float64), 4u);
    auto unknown = parse_raw_type("float");
    ASSERT_FALSE(unknown);
    EXPECT_EQ(unknown.error().message, "unknown type 'float': choose int16, uint16, int32, uint32, float32, float64 or string");
    EXPECT_FALSE(parse_raw_type("Float32"));
    EXPECT_TRUE(parse_word_order("little"));
    auto order = parse_word_order("middle");
    ASSERT_FALSE(order);
    EXPECT_NE(order.error().message.find("choose big"), std::string::npos);
}

std::vector<std::uint16_t> encoded(std::string_view text, RawType type, WordOrder order = WordOrder::big, bool swap = false,
                                   std::optional<RawScale> scale = std::nullopt) {
    auto words = encode_value(text, RawLayout{type, order, swap}, scale);
    EXPECT_TRUE(words) << text << ": " << (words ? "" : words.error().message);
    return words ? *words : std::vector<std::uint16_t>{};
}

std::string refusal(std::string_view text, RawType type, std::optional<RawScale> scale = std::nullopt) {
    auto words = encode_value(text, RawLayout{type}, scale);
    EXPECT_FALSE(words) << text;
    if (words) return "";
    EXPECT_EQ(words.error().kind, ErrorKind::usage);
    return words.error().message;
}

TEST(RawValues, EncodesFloat32InTheFourByteOrders) {
    using W = std::vector<std::uint16_t>;
    EXPECT_EQ(encoded("12.5", RawType::float32), (W{0x4148, 0x0000}));                           // ABCD
    EXPECT_EQ(encoded("12.5", RawType::float32, WordOrder::little), (W{0x0000, 0x4148}));        // CDAB
    EXPECT_EQ(encoded("12.5", RawType::float32, WordOrder::big, true), (W{0x4841, 0x0000}));     // BADC
    EXPECT_EQ(encoded("12.5", RawType::float32, WordOrder::little, true), (W{0x0000, 0x4841}));  // DCBA
    EXPECT_EQ(encoded("0.1", RawType::float32), (W{0x3DCC, 0xCCCD}));
    EXPECT_EQ(encoded("3.141592653589793", RawType::float64, WordOrder::little), (W{0x2D18, 0x5444, 0x21FB, 0x4009}));
    EXPECT_EQ(encoded("-2", RawType::int32), (W{0xFFFF, 0xFFFE}));
    EXPECT_EQ(encoded("123456789", RawType::int32, WordOrder::little), (W{0xCD15, 0x075B}));
    EXPECT_EQ(encoded("0xFFFF", RawType::int16), (W{0xFFFF}));  // a bit pattern, as register maps give them
    EXPECT_EQ(encoded("0x1234", RawType::uint16, WordOrder::big, true), (W{0x3412}));
}

TEST(RawValues, EncodingIsTheInverseOfDecoding) {
    const std::vector<std::pair<RawType, std::vector<const char*>>> samples{
        {RawType::int16, {"-32768", "-1", "0", "32767"}},
        {RawType::uint16, {"0", "1", "65535"}},
        {RawType::int32, {"-2147483648", "-2", "2147483647"}},
        {RawType::uint32, {"0", "65536", "4294967295"}},
        {RawType::float32, {"12.5", "-3.25", "0.1", "273.15", "10000000000", "-0"}},
        {RawType::float64, {"3.141592653589793", "-1e-300", "6.02214076e+23"}},
    };
    for (const auto& [type, texts] : samples) {
        for (const auto order : {WordOrder::big, WordOrder::little}) {
            for (const bool swap : {false, true}) {
                for (const char* text : texts) {
                    const RawLayout layout{type, order, swap};
                    const auto words = encoded(text, type, order, swap);
                    ASSERT_EQ(words.size(), registers_per_value(type)) << text;
                    EXPECT_EQ(number_text(decode_value(words, layout)), text) << raw_type_name(type) << " " << text;
                }
            }
        }
    }
}

TEST(RawValues, ScaledWritesHoldWholeSteps) {
    const auto tenth = parse_scale("0.1");
    ASSERT_TRUE(tenth);
    EXPECT_EQ(encoded("123.4", RawType::int16, WordOrder::big, false, *tenth), std::vector<std::uint16_t>{1234});
    EXPECT_EQ(encoded("-0.5", RawType::int16, WordOrder::big, false, *tenth), std::vector<std::uint16_t>{0xFFFB});
    EXPECT_EQ(encoded("12.5", RawType::float32, WordOrder::big, false, *parse_scale("0.5")),
              (std::vector<std::uint16_t>{0x41C8, 0x0000}));  // 25.0
    EXPECT_EQ(refusal("12.34", RawType::int16, *tenth), "12.34 with --scale 0.1 is 123.4 steps of 0.1: int16 holds whole steps only; "
                                                         "give 12.3 or 12.4");
    EXPECT_EQ(refusal("4000", RawType::int16, *tenth), "4000 does not fit int16: give -3276.8..3276.7 (with --scale 0.1)");
}

TEST(RawValues, EncodingRefusesWhatTheTypeCannotHold) {
    EXPECT_EQ(refusal("12.5", RawType::int16), "'12.5' is not a whole number for int16: give a whole number -32768..32767 (or "
                                               "--type float32 for a fraction)");
    EXPECT_EQ(refusal("abc", RawType::uint32), "'abc' is not a number for uint32: give a whole number 0..4294967295");
    EXPECT_EQ(refusal("70000", RawType::uint16), "70000 does not fit uint16: give 0..65535");
    EXPECT_EQ(refusal("-1", RawType::uint32), "-1 does not fit uint32: give 0..4294967295");
    EXPECT_EQ(refusal("2147483648", RawType::int32), "2147483648 does not fit int32: give -2147483648..2147483647");
    EXPECT_EQ(refusal("0x10000", RawType::int16), "0x10000 does not fit int16: give -32768..32767");
    EXPECT_NE(refusal("1e39", RawType::float32).find("beyond the largest float32"), std::string::npos);
    // Too large for a double too: read as infinity, which only "inf" asks for.
    EXPECT_EQ(refusal("1e999", RawType::float32), "1e999 is beyond the largest float32, 3.4028235e+38: give a smaller number");
    EXPECT_EQ(refusal("-1e309", RawType::float64),
              "-1e309 is beyond the largest float64, 1.7976931348623157e+308: give a smaller number");
    EXPECT_NE(refusal("12,5", RawType::float32).find("'12,5' is not a number for float32"), std::string::npos);
    EXPECT_NE(refusal(" 1", RawType::float64).find("is not a number"), std::string::npos);
    EXPECT_NE(refusal("", RawType::int16).find("is not a number"), std::string::npos);
}

// The largest float32 as it is printed, 3.4028235e+38, is a little above the float itself as a
// double, yet rounds to it; infinity is written when named.
TEST(RawValues, TheLargestFloatAsPrintedAndInfinityByNameAreTaken) {
    using W = std::vector<std::uint16_t>;
    EXPECT_EQ(encoded("3.4028235e38", RawType::float32), (W{0x7F7F, 0xFFFF}));
    EXPECT_EQ(encoded("-3.4028235e+38", RawType::float32), (W{0xFF7F, 0xFFFF}));
    EXPECT_EQ(encoded("inf", RawType::float32), (W{0x7F80, 0x0000}));
    EXPECT_EQ(encoded("-Infinity", RawType::float32), (W{0xFF80, 0x0000}));
    EXPECT_EQ(encoded("inf", RawType::float64), (W{0x7FF0, 0x0000, 0x0000, 0x0000}));
}

TEST(RawValues, WordOrdersByTheirByteOrderNames) {
    const std::vector<std::tuple<const char*, WordOrder, bool>> names{
        {"ABCD", WordOrder::big, false}, {"CDAB", WordOrder::little, false},
        {"BADC", WordOrder::big, true}, {"DCBA", WordOrder::little, true}};
    for (const auto& [name, order, swap] : names) {
        auto choice = parse_word_order(name);
        ASSERT_TRUE(choice) << name;
        EXPECT_EQ(choice->order, order) << name;
        ASSERT_TRUE(choice->byte_swap.has_value()) << name;
        EXPECT_EQ(*choice->byte_swap, swap) << name;
        EXPECT_EQ(byte_order_name(RawLayout{RawType::float32, order, swap}), name);
    }
    auto big = parse_word_order("big");
    ASSERT_TRUE(big);
    EXPECT_FALSE(big->byte_swap.has_value());  // says nothing about the bytes: --byte-swap may add it
    EXPECT_FALSE(parse_word_order("abcd"));
}

TEST(RawValues, ScaleIsExactToTheDecimal) {
    auto tenth = parse_scale("0.1");
    ASSERT_TRUE(tenth) << tenth.error().message;
    EXPECT_EQ(number_text(scaled(std::int64_t{1234}, *tenth)), "123.4");
    EXPECT_EQ(scaled(std::int64_t{1234}, *tenth), 123.4);
    EXPECT_EQ(scaled(std::int64_t{-5}, *parse_scale("2")), -10.0);
    EXPECT_EQ(scaled(12.5, *parse_scale("-0.25")), -3.125);
    EXPECT_EQ(scaled(std::int64_t{7}, *parse_scale("+0.010")), 0.07);
    for (const char* bad : {"", "abc", "1e3", ".5", "5.", "0", "0.000", "1,5", "--1", "0x10", "1.0000000000000001"}) {
        auto refused = parse_scale(bad);
        EXPECT_FALSE(refused) << bad;
        if (!refused) {
            EXPECT_EQ(refused.error().kind, ErrorKind::usage) << bad;
        }
    }
}

TEST(RawValues, StringsAreTwoAsciiCharactersARegisterInEitherByteOrder) {
    const RawLayout high_first{RawType::string, WordOrder::big, false};
    const RawLayout low_first{RawType::string, WordOrder::big, true};
    auto odd = encode_value("AB1", high_first);
    ASSERT_TRUE(odd) << odd.error().message;
    EXPECT_EQ(*odd, (std::vector<std::uint16_t>{0x4142, 0x3100}));  // padded with NUL
    auto swapped = encode_value("AB1", low_first);
    ASSERT_TRUE(swapped);
    EXPECT_EQ(*swapped, (std::vector<std::uint16_t>{0x4241, 0x0031}));
    EXPECT_EQ(*encode_value("", high_first), std::vector<std::uint16_t>{0});
    // Reading stops at the first NUL; the word order leaves the text's registers in order.
    const std::vector<std::uint16_t> words{0x4142, 0x3100, 0x4344};
    EXPECT_EQ(decode_value(words, high_first), RawNumber(std::string("AB1")));
    EXPECT_EQ(decode_value(words, RawLayout{RawType::string, WordOrder::little, false}), RawNumber(std::string("AB1")));
    EXPECT_EQ(decode_value(std::vector<std::uint16_t>{0x4241, 0x0031}, low_first), RawNumber(std::string("AB1")));
    EXPECT_EQ(decode_value(std::vector<std::uint16_t>{0x4142, 0x4344}, high_first), RawNumber(std::string("ABCD")));  // no NUL: all of it
    EXPECT_EQ(number_text(decode_value(words, high_first)), "AB1");
}

TEST(RawValues, StringsRefuseWhatIsNotAsciiAndEscapeItWhenRead) {
    auto accented = encode_value("Grüße", RawLayout{RawType::string, WordOrder::big, false});
    ASSERT_FALSE(accented);
    EXPECT_EQ(accented.error().kind, ErrorKind::usage);
    EXPECT_NE(accented.error().message.find("is not printable ASCII text"), std::string::npos) << accented.error().message;
    EXPECT_FALSE(encode_value("tab\there", RawLayout{RawType::string, WordOrder::big, false}));
    // A device's bytes that are not printable ASCII cannot reach a terminal or a JSON line raw.
    EXPECT_EQ(decode_value(std::vector<std::uint16_t>{0x41FF, 0x0742}, RawLayout{RawType::string, WordOrder::big, false}),
              RawNumber(std::string("A\\xFF\\x07B")));
    EXPECT_TRUE(parse_raw_type("string"));
}

}  // namespace
}  // namespace loopwire::device
