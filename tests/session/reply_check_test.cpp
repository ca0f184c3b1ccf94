// What answers what (session/reply_check.hpp): a reply is taken only when it answers the request
// in function and shape, for PDUs passed through as they are (the gateway's path) and for typed
// requests alike. Each case is a reply that a stale or duplicated frame of another request of
// the same function could be.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "session/reply_check.hpp"
#include "support/test_bytes.hpp"

namespace loopwire::session {
namespace {

using loopwire::testing::hex;

struct Case {
    std::string what;
    Bytes request;
    Bytes reply;
    bool answers;
};

// Modbus application protocol V1.1b3, 6 and 7: every function code loopwire knows the shape of,
// each with its right reply, its exception reply, and every way a reply can miss.
const std::vector<Case> forwarded_cases{
    // FC1/2: byte count = ceil(quantity / 8) (6.1, 6.2)
    {"FC1 19 coils: 3 bytes", hex("01 00 13 00 13"), hex("01 03 CD 6B 05"), true},
    {"FC1 8 coils: 1 byte", hex("01 00 00 00 08"), hex("01 01 FF"), true},
    {"FC1 9 coils answered with 1 byte", hex("01 00 00 00 09"), hex("01 01 FF"), false},
    {"FC1 byte count right, a byte too many", hex("01 00 13 00 13"), hex("01 03 CD 6B 05 00"), false},
    {"FC1 byte count right, a byte short", hex("01 00 13 00 13"), hex("01 03 CD 6B"), false},
    {"FC2 22 inputs: 3 bytes", hex("02 00 C4 00 16"), hex("02 03 AC DB 35"), true},
    {"FC2 22 inputs answered with 4 bytes", hex("02 00 C4 00 16"), hex("02 04 AC DB 35 00"), false},
    // FC3/4: byte count = 2 x quantity (6.3, 6.4)
    {"FC3 one register", hex("03 03 09 00 01"), hex("03 02 03 09"), true},
    {"FC3 one register answered with two", hex("03 03 09 00 01"), hex("03 04 03 09 00 14"), false},
    {"FC3 two registers answered with one", hex("03 00 6B 00 02"), hex("03 02 02 2B"), false},
    {"FC3 byte count 2, four data bytes", hex("03 03 09 00 01"), hex("03 02 03 09 00 14"), false},
    {"FC3 without a byte count", hex("03 03 09 00 01"), hex("03"), false},
    {"FC4 one register", hex("04 00 08 00 01"), hex("04 02 00 0A"), true},
    {"FC4 odd byte count", hex("04 00 08 00 01"), hex("04 03 00 0A 00"), false},
    // FC5/6: the echo of the request (6.5, 6.6)
    {"FC5 echo", hex("05 00 AC FF 00"), hex("05 00 AC FF 00"), true},
    {"FC5 echo of another address", hex("05 00 AC FF 00"), hex("05 00 AD FF 00"), false},
    {"FC5 echo of another value", hex("05 00 AC FF 00"), hex("05 00 AC 00 00"), false},
    {"FC6 echo", hex("06 00 01 00 03"), hex("06 00 01 00 03"), true},
    {"FC6 echo of another value", hex("06 00 01 00 03"), hex("06 00 01 00 04"), false},
    {"FC6 echo cut short", hex("06 00 01 00 03"), hex("06 00 01 00"), false},
    {"FC6 echo with a byte more", hex("06 00 01 00 03"), hex("06 00 01 00 03 00"), false},
    // FC15/16: address and quantity (6.11, 6.12)
    {"FC15 address and quantity", hex("0F 00 13 00 0A 02 CD 01"), hex("0F 00 13 00 0A"), true},
    {"FC15 another quantity", hex("0F 00 13 00 0A 02 CD 01"), hex("0F 00 13 00 09"), false},
    {"FC16 address and quantity", hex("10 00 01 00 02 04 00 0A 01 02"), hex("10 00 01 00 02"), true},
    {"FC16 another address", hex("10 00 01 00 02 04 00 0A 01 02"), hex("10 00 02 00 02"), false},
    {"FC16 another quantity", hex("10 00 01 00 02 04 00 0A 01 02"), hex("10 00 01 00 01"), false},
    // FC23: byte count = 2 x the quantity read (6.17)
    {"FC23 six registers read", hex("17 00 03 00 06 00 0E 00 03 06 00 FF 00 FF 00 FF"),
     hex("17 0C 00 FE 0A CD 00 01 00 03 00 0D 00 FF"), true},
    {"FC23 answered with the quantity written", hex("17 00 03 00 06 00 0E 00 03 06 00 FF 00 FF 00 FF"),
     hex("17 06 00 FE 0A CD 00 01"), false},
    // Exception replies: function | 80h and one code byte (7)
    {"FC3 exception", hex("03 03 09 00 01"), hex("83 02"), true},
    {"FC3 exception with a byte more", hex("03 03 09 00 01"), hex("83 02 00"), false},
    {"FC3 exception without its code", hex("03 03 09 00 01"), hex("83"), false},
    {"FC4's exception to an FC3 request", hex("03 03 09 00 01"), hex("84 02"), false},
    // Another function altogether
    {"FC4 reply to an FC3 request", hex("03 03 09 00 01"), hex("04 02 03 09"), false},
    {"an empty reply", hex("03 03 09 00 01"), Bytes{}, false},
    // Function codes whose replies loopwire cannot know the shape of: the code is all there is.
    {"FC43 device identification", hex("2B 0E 01 00"), hex("2B 0E 01 01 00 00 01 00 03 41 42 43"), true},
    {"FC8 diagnostics", hex("08 00 00 A5 37"), hex("08 00 00 A5 37 00"), true},
    {"FC65 vendor code", hex("41 01"), hex("41"), true},
    {"FC65 answered by FC66", hex("41 01"), hex("42 01"), false},
    // A request that is itself malformed: the device answers it with an exception; a normal
    // reply is checked on its function only, as no shape can be derived.
    {"FC3 request cut short", hex("03 00 01"), hex("03 02 00 00"), true},
};

TEST(ReplyCheck, AForwardedPduIsAnsweredOnlyByAReplyOfItsFunctionAndShape) {
    for (const auto& c : forwarded_cases) {
        auto check = answers_forwarded(c.request);
        auto verdict = check(c.reply);
        EXPECT_EQ(verdict.ok(), c.answers) << c.what << ": " << (verdict.ok() ? "taken" : verdict.error().message);
        if (!verdict.ok()) {
            EXPECT_TRUE(verdict.error().kind == ErrorKind::mismatch || verdict.error().kind == ErrorKind::malformed)
                << c.what;
            EXPECT_FALSE(verdict.error().message.empty()) << c.what;
        }
    }
}

TEST(ReplyCheck, AMismatchSaysWhatWasAskedAndWhatCame) {
    auto byte_count = answers_forwarded(hex("03 03 09 00 01"))(hex("03 04 03 09 00 14"));
    ASSERT_FALSE(byte_count.ok());
    EXPECT_EQ(byte_count.error().message, "FC3 reply: byte count 4, the request asked for 2 bytes");

    auto length = answers_forwarded(hex("03 03 09 00 01"))(hex("03 02 03 09 00 14"));
    ASSERT_FALSE(length.ok());
    EXPECT_EQ(length.error().message, "FC3 reply: 6 bytes, byte count 2 makes 4");

    auto echo = answers_forwarded(hex("06 00 01 00 03"))(hex("06 00 01 00 04"));
    ASSERT_FALSE(echo.ok());
    EXPECT_EQ(echo.error().message,
              "FC6 reply echoes 0001h 0004h, the request was 0001h 0003h (address and value)");

    auto function = answers_forwarded(hex("03 03 09 00 01"))(hex("04 02 03 09"));
    ASSERT_FALSE(function.ok());
    EXPECT_EQ(function.error().message, "the reply is for function 4, the request was function 3");
}

// The typed path (codec::match_reply) is as strict: the same replies are refused for the same
// requests built as codec::Request.
TEST(ReplyCheck, ATypedRequestIsAnsweredOnlyByAReplyOfItsFunctionAndShape) {
    struct TypedCase {
        std::string what;
        codec::Request request;
        Bytes reply;
        bool answers;
    };
    using codec::FunctionCode;
    const std::vector<TypedCase> cases{
        {"FC1 19 coils", codec::read_request(FunctionCode::read_coils, 19, 19), hex("01 03 CD 6B 05"), true},
        {"FC1 9 coils answered with 1 byte", codec::read_request(FunctionCode::read_coils, 0, 9), hex("01 01 FF"), false},
        {"FC2 22 inputs answered with 4 bytes", codec::read_request(FunctionCode::read_discrete_inputs, 196, 22),
         hex("02 04 AC DB 35 00"), false},
        {"FC3 one register", codec::read_request(FunctionCode::read_holding_registers, 777, 1), hex("03 02 03 09"), true},
        {"FC3 one register answered with two", codec::read_request(FunctionCode::read_holding_registers, 777, 1),
         hex("03 04 03 09 00 14"), false},
        {"FC3 byte count 2, four data bytes", codec::read_request(FunctionCode::read_holding_registers, 777, 1),
         hex("03 02 03 09 00 14"), false},
        {"FC4 two answered with one", codec::read_request(FunctionCode::read_input_registers, 8, 2), hex("04 02 00 0A"),
         false},
        {"FC5 echo of another address", codec::write_single_coil(172, true), hex("05 00 AD FF 00"), false},
        {"FC5 echo of another value", codec::write_single_coil(172, true), hex("05 00 AC 00 00"), false},
        {"FC6 echo", codec::write_single_register(1, 3), hex("06 00 01 00 03"), true},
        {"FC6 echo of another value", codec::write_single_register(1, 3), hex("06 00 01 00 04"), false},
        {"FC15 another quantity", codec::write_multiple_coils(19, {1, 0, 1, 1, 0, 0, 1, 1, 1, 0}),
         hex("0F 00 13 00 09"), false},
        {"FC16 another address", codec::write_multiple_registers(1, {10, 258}), hex("10 00 02 00 02"), false},
        {"FC16 address and quantity", codec::write_multiple_registers(1, {10, 258}), hex("10 00 01 00 02"), true},
        {"FC3 exception", codec::read_request(FunctionCode::read_holding_registers, 777, 1), hex("83 02"), true},
        {"FC3 exception with a byte more", codec::read_request(FunctionCode::read_holding_registers, 777, 1),
         hex("83 02 00"), false},
        {"FC4's exception to an FC3 request", codec::read_request(FunctionCode::read_holding_registers, 777, 1),
         hex("84 02"), false},
    };
    for (const auto& c : cases) {
        auto verdict = answers_request(c.request)(c.reply);
        EXPECT_EQ(verdict.ok(), c.answers) << c.what << ": " << (verdict.ok() ? "taken" : verdict.error().message);
    }
}

}  // namespace
}  // namespace loopwire::session
