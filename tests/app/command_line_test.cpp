#include <gtest/gtest.h>

#include "app/command_line.hpp"
#include "app/exit_codes.hpp"

namespace loopwire::app {
namespace {

using std::chrono::microseconds;

TEST(ParseDuration, AcceptsTheUnitsPeopleWrite) {
    EXPECT_EQ(*parse_duration("500ms"), microseconds(500'000));
    EXPECT_EQ(*parse_duration("2s"), microseconds(2'000'000));
    EXPECT_EQ(*parse_duration("1.5s"), microseconds(1'500'000));
    EXPECT_EQ(*parse_duration("1m"), microseconds(60'000'000));
    EXPECT_EQ(*parse_duration("250us"), microseconds(250));
    EXPECT_EQ(*parse_duration("300"), microseconds(300'000));  // bare numbers are milliseconds
}

TEST(ParseDuration, RejectsGarbageWithAnExample) {
    for (const char* bad : {"", "fast", "5 parsecs", "-1s", "2h", "1e9s"}) {
        auto parsed = parse_duration(bad);
        ASSERT_FALSE(parsed.ok()) << bad;
        EXPECT_EQ(parsed.error().kind, ErrorKind::usage);
        EXPECT_NE(parsed.error().message.find(bad), std::string::npos);
    }
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
    EXPECT_FALSE(parse_integer("12ab", 0, 65535, "address").ok());
    EXPECT_FALSE(parse_integer("0x", 0, 65535, "address").ok());
}

TEST(ExitCodes, EachErrorKindHasItsOwnStatus) {
    EXPECT_EQ(exit_code_for(make_error(ErrorKind::usage, "")), 2);
    EXPECT_EQ(exit_code_for(make_error(ErrorKind::link, "")), 3);
    EXPECT_EQ(exit_code_for(make_error(ErrorKind::timeout, "")), 4);
    EXPECT_EQ(exit_code_for(make_error(ErrorKind::exception, "", 2)), 5);
    EXPECT_EQ(exit_code_for(make_error(ErrorKind::mismatch, "")), 6);
}

}  // namespace
}  // namespace loopwire::app
