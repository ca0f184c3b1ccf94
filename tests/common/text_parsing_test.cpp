#include <gtest/gtest.h>

#include "common/text_parsing.hpp"

namespace loopwire {
namespace {

using std::chrono::microseconds;
using std::chrono::milliseconds;

TEST(ParseDuration, AcceptsTheUnitsPeopleWrite) {
    EXPECT_EQ(*parse_duration("500ms"), microseconds(500'000));
    EXPECT_EQ(*parse_duration("2s"), microseconds(2'000'000));
    EXPECT_EQ(*parse_duration("1.5s"), microseconds(1'500'000));
    EXPECT_EQ(*parse_duration("1m"), microseconds(60'000'000));
    EXPECT_EQ(*parse_duration("1min"), microseconds(60'000'000));
    EXPECT_EQ(*parse_duration("250us"), microseconds(250));
    EXPECT_EQ(*parse_duration("300"), microseconds(300'000));  // bare numbers are milliseconds
    EXPECT_EQ(*parse_duration("0.1s"), microseconds(100'000));
    EXPECT_EQ(*parse_duration("1h"), microseconds(3'600'000'000));
    EXPECT_EQ(*parse_duration("24h"), microseconds(86'400'000'000));  // what the day limit's message suggests
}

TEST(ParseDuration, RejectsGarbageWithAnExample) {
    for (const char* bad : {"", "fast", "5 parsecs", "-1s", "2d", "1e9s", "1.2.3s", "1..2s", "1.s", ".5s", "1.5.s", "+2s",
                            " 2s", "2s ", "0x10ms", "1,5s", "nan", "infs"}) {
        auto parsed = parse_duration(bad, "--timeout");
        ASSERT_FALSE(parsed.ok()) << bad;
        EXPECT_EQ(parsed.error().kind, ErrorKind::usage);
        EXPECT_NE(parsed.error().message.find(std::string("--timeout '") + bad + "'"), std::string::npos) << parsed.error().message;
        EXPECT_NE(parsed.error().message.find("500ms, 2s, 1.5s, 1m or 1h"), std::string::npos) << parsed.error().message;
    }
}

TEST(ParseDuration, ZeroIsRefusedWhereALeastIsGiven) {
    EXPECT_EQ(*parse_duration("0", "--duration"), microseconds(0));  // a run of no length is a valid request
    for (const char* zero : {"0", "0ms", "0s", "0.0s", "0.4us", "999us"}) {
        auto parsed = parse_duration(zero, "--timeout", milliseconds(1));
        ASSERT_FALSE(parsed.ok()) << zero;
        EXPECT_NE(parsed.error().message.find("--timeout"), std::string::npos) << parsed.error().message;
        EXPECT_NE(parsed.error().message.find("at least 1ms"), std::string::npos) << parsed.error().message;
    }
    EXPECT_EQ(*parse_duration("1ms", "--timeout", milliseconds(1)), microseconds(1000));
}

TEST(ParseDuration, LongerThanADayIsRefused) {
    EXPECT_FALSE(parse_duration("1441m").ok());
    auto longer = parse_duration("25h", "--interval");
    ASSERT_FALSE(longer.ok());
    EXPECT_EQ(longer.error().message, "--interval '25h' is longer than a day; give at most 24h, e.g. 1440m");
    EXPECT_FALSE(parse_duration("99999999999999999999999s").ok());
}

TEST(ParsePeriod, DaysHoursMinutesSeconds) {
    using std::chrono::seconds;
    EXPECT_EQ(*parse_period("90d"), seconds(90 * 86400));
    EXPECT_EQ(*parse_period("1.5d"), seconds(129600));
    EXPECT_EQ(*parse_period("12h"), seconds(43200));
    EXPECT_EQ(*parse_period("30m"), seconds(1800));
    EXPECT_EQ(*parse_period("30min"), seconds(1800));
    EXPECT_EQ(*parse_period("3600s"), seconds(3600));
}

TEST(ParsePeriod, RejectsGarbageAndExtremes) {
    for (const char* bad : {"", "90", "d", "90 d", "-1d", "1..5d", "1.d", ".5d", "1.2.3d", "90days", "1e3d", "nan"}) {
        auto parsed = parse_period(bad, "history.keep");
        ASSERT_FALSE(parsed.ok()) << bad;
        EXPECT_EQ(parsed.error().message, std::string("history.keep '") + bad + "' is not a period: write it like 90d, 12h, 30m or 3600s");
    }
    EXPECT_NE(parse_period("40000d").error().message.find("longer than 100 years"), std::string::npos);
    EXPECT_NE(parse_period("0d").error().message.find("too short: give at least 1s"), std::string::npos);
}

TEST(ParseInteger, DecimalHexAndManualStyleHex) {
    EXPECT_EQ(*parse_integer("201", 0, 65535, "address"), 201);
    EXPECT_EQ(*parse_integer("0xC9", 0, 65535, "address"), 201);
    EXPECT_EQ(*parse_integer("C9h", 0, 65535, "address"), 201);
    EXPECT_EQ(*parse_integer("-100", -32768, 65535, "value"), -100);
}

TEST(ParseInteger, SaysWhatWasOutOfRange) {
    auto parsed = parse_integer("70000", 0, 65535, "address");
    ASSERT_FALSE(parsed.ok());
    EXPECT_NE(parsed.error().message.find("address 70000 is out of range 0..65535"), std::string::npos) << parsed.error().message;
    for (const char* bad : {"12ab", "0x", "", "-", "+-5", "0x-5", "1 ", "1.0"}) {
        EXPECT_FALSE(parse_integer(bad, -65535, 65535, "address").ok()) << bad;
    }
}

TEST(ParseDecimalDigits, WholeUnsignedDecimalOnly) {
    EXPECT_EQ(parse_decimal_digits("19200"), 19200u);
    EXPECT_EQ(parse_decimal_digits("0"), 0u);
    for (const char* bad : {"", "+1", "-1", " 1", "1 ", "0x10", "10h", "1.0", "99999999999999999999999"}) {
        EXPECT_FALSE(parse_decimal_digits(bad).has_value()) << bad;
    }
}

}  // namespace
}  // namespace loopwire
