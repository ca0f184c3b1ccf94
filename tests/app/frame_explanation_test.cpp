// `loopwire decode` explanations of the manuals' example frames.
#include <gtest/gtest.h>

#include "app/frame_explanation.hpp"

namespace loopwire::app {
namespace {

FrameExplanation explain(const std::string& protocol, const std::string& hex, const std::string& direction = "") {
    auto bytes = parse_hex(hex);
    EXPECT_TRUE(bytes.has_value());
    auto e = explain_frame(protocol, direction, *bytes);
    EXPECT_TRUE(e.ok());
    return *e;
}

// AC20 manual, "Function code 1 and 2", Example request: slave 100, bits from 201, 14 of them.
TEST(FrameExplanation, Ac20Fc1RequestAsTheIssueShowsIt) {
    auto json = to_json(explain("rtu", "64 01 00 C9 00 0E 64 05"));
    EXPECT_EQ(json.dump(), R"({"protocol":"rtu","unit":100,"function":1,"kind":"request","address":201,"count":14,"values":[],"exception":null,"check_ok":true,"error":null})");
}

// AC20 manual, "Function codes 3 and 4", Example reply: FF9Ch, 8000h, 055Ah.
TEST(FrameExplanation, Ac20Fc3ReplyValuesAreUnsignedWords) {
    auto e = explain("rtu", "1D 03 06 FF 9C 80 00 05 5A D7 0D");
    EXPECT_EQ(e.kind, "reply");
    EXPECT_EQ(e.values, (std::vector<std::uint16_t>{65436, 32768, 1370}));
    EXPECT_TRUE(e.problem.empty());
}

// Ramp/soak manual §4.7.3: the FC16 exception frame is printed with CRC C0 01; the right one is
// CD C1. decode names the mismatch and still shows the fields.
TEST(FrameExplanation, RampSoakMisprintedCrcIsReportedWithBothValues) {
    auto e = explain("rtu", "01 90 02 C0 01");
    EXPECT_FALSE(e.check_ok);
    EXPECT_EQ(e.kind, "exception");
    EXPECT_EQ(e.exception, 2u);
    EXPECT_NE(e.problem.find("computed CD C1"), std::string::npos) << e.problem;
    EXPECT_TRUE(explain("rtu", "01 90 02 CD C1").problem.empty());
}

// Ramp/soak manual §5.7.2: ASCII exception reply with LRC 6D.
TEST(FrameExplanation, RampSoakAsciiException) {
    const std::string text = ":0190026D\r\n";
    auto e = explain_frame("ascii", "", Bytes(text.begin(), text.end()));
    ASSERT_TRUE(e.ok());
    EXPECT_EQ(e->kind, "exception");
    EXPECT_EQ(e->exception, 2u);
    EXPECT_TRUE(e->check_ok);
}

// Ramp/soak manual §6.7.1: Linking R request and its reply.
TEST(FrameExplanation, RampSoakLinkingReadAndReply) {
    auto request = explain("linking", "52 01 00 8A 00 00 DD");
    EXPECT_EQ(request.command, "R");
    EXPECT_EQ(request.address, 0x8Au);
    EXPECT_TRUE(request.check_ok);
    auto reply = explain("linking", "07 4D 01 00 8A 03 E8 C3");
    EXPECT_EQ(reply.kind, "reply");
    EXPECT_EQ(reply.values, (std::vector<std::uint16_t>{1000}));
    EXPECT_TRUE(reply.check_ok);
}

// TC10 manual §3.3 FC16 request, carried in an MBAP header instead of RTU.
TEST(FrameExplanation, TcpFrameShowsTheTransaction) {
    auto e = explain("tcp", "00 07 00 00 00 0B 01 10 28 4A 00 02 04 00 64 00 C8");
    EXPECT_EQ(e.transaction, 7u);
    EXPECT_EQ(e.address, 10314u);
    EXPECT_EQ(e.values, (std::vector<std::uint16_t>{100, 200}));
}

TEST(FrameExplanation, EchoFramesReadAsRequestsUnlessToldOtherwise) {
    // AC20 manual, "Function code 6", Example: the reply echoes the request.
    EXPECT_EQ(explain("rtu", "05 06 07 D6 04 E2 EA 4B").kind, "request");
    EXPECT_EQ(explain("rtu", "05 06 07 D6 04 E2 EA 4B", "reply").kind, "reply");
}

TEST(FrameExplanation, TooShortAndUnknownProtocol) {
    EXPECT_NE(explain("rtu", "01 03 00").problem.find("at least 4 bytes"), std::string::npos);
    EXPECT_FALSE(explain_frame("bacnet", "", Bytes{1, 2, 3}).ok());
}

}  // namespace
}  // namespace loopwire::app
