// PDU codec tests: encoding, decoding and validation of FC 1-6, 15, 16 against the Modbus
// Application Protocol V1.1b3 section 6 and the field layouts the device manuals print.
// Where a test uses bytes from a manual, the comment names the manual and section; the whole
// RTU frames (with CRC) are replayed in rtu_test.cpp.
#include "codec/pdu.hpp"
#include "codec/table.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/test_bytes.hpp"

#include <string_view>

namespace loopwire::codec {
namespace {

using loopwire::testing::hex;

using ::testing::ElementsAre;
using ::testing::HasSubstr;

std::vector<std::uint16_t> repeated(std::size_t count, std::uint16_t value) {
    return std::vector<std::uint16_t>(count, value);
}

// Encodes `request` and expects ErrorKind::usage whose message contains `fragment`.
void expect_request_rejected(const Request& request, std::string_view fragment) {
    const auto encoded = encode_request(request);
    ASSERT_FALSE(encoded.ok()) << "encoded to " << to_hex(encoded.value());
    EXPECT_EQ(encoded.error().kind, ErrorKind::usage);
    EXPECT_THAT(encoded.error().message, HasSubstr(std::string(fragment)));
}

void expect_request_pdu_malformed(std::string_view pdu_hex, std::string_view fragment) {
    const auto decoded = decode_request(hex(pdu_hex));
    ASSERT_FALSE(decoded.ok()) << "PDU " << pdu_hex << " decoded";
    EXPECT_EQ(decoded.error().kind, ErrorKind::malformed);
    EXPECT_THAT(decoded.error().message, HasSubstr(std::string(fragment)));
}

void expect_reply_pdu_malformed(std::string_view pdu_hex, std::string_view fragment) {
    const auto decoded = decode_reply(hex(pdu_hex));
    ASSERT_FALSE(decoded.ok()) << "PDU " << pdu_hex << " decoded";
    EXPECT_EQ(decoded.error().kind, ErrorKind::malformed);
    EXPECT_THAT(decoded.error().message, HasSubstr(std::string(fragment)));
}

void expect_mismatch(const Request& request, const Reply& reply, std::string_view fragment) {
    const auto matched = match_reply(request, reply);
    ASSERT_FALSE(matched.ok());
    EXPECT_EQ(matched.error().kind, ErrorKind::mismatch);
    EXPECT_THAT(matched.error().message, HasSubstr(std::string(fragment)));
}

Reply decoded_reply(std::string_view pdu_hex) {
    auto reply = decode_reply(hex(pdu_hex));
    EXPECT_TRUE(reply.ok()) << (reply.ok() ? "" : reply.error().message);
    return reply.ok() ? reply.value() : Reply{};
}

// ---- names ----------------------------------------------------------------------------------

TEST(PduNames, SupportedFunctionsAreExactlyTheEight) {
    for (int fc = 0; fc < 256; ++fc) {
        const bool expected = (fc >= 1 && fc <= 6) || fc == 15 || fc == 16;
        EXPECT_EQ(is_supported_function(static_cast<std::uint8_t>(fc)), expected) << fc;
    }
}

TEST(PduNames, FunctionNamesAndUnknownCodes) {
    EXPECT_EQ(function_name(3), "read holding registers");
    EXPECT_EQ(function_name(15), "write multiple coils");
    EXPECT_EQ(function_name(43), "function 43");
}

TEST(PduNames, ExceptionNamesOnlyForStandardCodes) {
    EXPECT_EQ(exception_name(2), "illegal data address");
    EXPECT_EQ(exception_name(6), "server device busy");
    EXPECT_EQ(exception_name(8), "memory parity error");
    EXPECT_EQ(exception_name(0x0A), "gateway path unavailable");
    EXPECT_EQ(exception_name(0x0B), "gateway target device failed to respond");
    EXPECT_EQ(describe_exception(0x0B), "11 (gateway target device failed to respond)");
    EXPECT_EQ(exception_name(7), std::nullopt);  // not defined by the specification
    EXPECT_EQ(exception_name(101), std::nullopt);  // AC20 device-specific code
    EXPECT_EQ(describe_exception(2), "2 (illegal data address)");
    EXPECT_EQ(describe_exception(101), "101");
}

// ---- bit packing (V1.1b3 6.1 / AC20 "Function code 1 and 2": lowest address in bit 0) -------

TEST(PduBits, PackAc20Fc15ExampleBits) {
    // AC20 "Function code 15" example: bits 224..232 = 0,1,1,0,1,0,1,1,1 -> D6h 01h.
    EXPECT_EQ(pack_bits({0, 1, 1, 0, 1, 0, 1, 1, 1}), hex("D6 01"));
}

TEST(PduBits, PackPadsWithZeroAndUsesWholeBytes) {
    EXPECT_EQ(pack_bits({}), Bytes{});
    EXPECT_EQ(pack_bits({1}), hex("01"));
    EXPECT_EQ(pack_bits(repeated(8, 1)), hex("FF"));
    EXPECT_EQ(pack_bits(repeated(9, 1)), hex("FF 01"));
}

TEST(PduBits, UnpackAc20Fc01ExampleBits) {
    // AC20 "Function code 1 and 2" example: A7h 04h = bits 201..214 as listed in the manual.
    EXPECT_THAT(unpack_bits(hex("A7 04"), 14), ElementsAre(1, 1, 1, 0, 0, 1, 0, 1, 0, 0, 1, 0, 0, 0));
}

TEST(PduBits, UnpackNeverReadsPastTheBytesGiven) {
    EXPECT_EQ(unpack_bits(hex("FF"), 20).size(), 8u);
    EXPECT_TRUE(unpack_bits({}, 5).empty());
}

TEST(PduBits, PackUnpackRoundTrip) {
    const std::vector<std::uint16_t> states{1, 0, 0, 1, 1, 1, 0, 1, 0, 1, 1};
    EXPECT_EQ(unpack_bits(pack_bits(states), states.size()), states);
}

// ---- request encoding -----------------------------------------------------------------------

TEST(PduEncodeRequest, ReadCoilsAc20Example) {
    // AC20 "Function code 1 and 2" example: bits from 201, 14 of them.
    EXPECT_EQ(encode_request(read_request(FunctionCode::read_coils, 201, 14)).value(), hex("01 00 C9 00 0E"));
}

TEST(PduEncodeRequest, ReadRegistersAllFourReadFunctions) {
    EXPECT_EQ(encode_request(read_request(FunctionCode::read_discrete_inputs, 1, 2)).value(),
              hex("02 00 01 00 02"));
    EXPECT_EQ(encode_request(read_request(FunctionCode::read_holding_registers, 178, 3)).value(),
              hex("03 00 B2 00 03"));
    EXPECT_EQ(encode_request(read_request(FunctionCode::read_input_registers, 0x1234, 125)).value(),
              hex("04 12 34 00 7D"));
}

TEST(PduEncodeRequest, WriteSingleCoilUsesFF00AndZero) {
    // V1.1b3 6.5 and AC20 "Function code 5": FF00h sets, 0000h resets.
    EXPECT_EQ(encode_request(write_single_coil(219, true)).value(), hex("05 00 DB FF 00"));
    EXPECT_EQ(encode_request(write_single_coil(219, false)).value(), hex("05 00 DB 00 00"));
}

TEST(PduEncodeRequest, WriteSingleRegister) {
    EXPECT_EQ(encode_request(write_single_register(2006, 1250)).value(), hex("06 07 D6 04 E2"));
}

TEST(PduEncodeRequest, WriteMultipleCoilsAc20Example) {
    EXPECT_EQ(encode_request(write_multiple_coils(224, {0, 1, 1, 0, 1, 0, 1, 1, 1})).value(),
              hex("0F 00 E0 00 09 02 D6 01"));
}

TEST(PduEncodeRequest, WriteMultipleRegistersAc20Example) {
    EXPECT_EQ(encode_request(write_multiple_registers(139, {300, 0x8000, 700})).value(),
              hex("10 00 8B 00 03 06 01 2C 80 00 02 BC"));
}

TEST(PduEncodeRequest, ReadQuantityLimits) {
    EXPECT_TRUE(encode_request(read_request(FunctionCode::read_coils, 0, 2000)).ok());
    expect_request_rejected(read_request(FunctionCode::read_coils, 0, 2001),
                            "FC1 request: quantity 2001 outside 1..2000");
    expect_request_rejected(read_request(FunctionCode::read_discrete_inputs, 0, 0),
                            "quantity 0 outside 1..2000");
    EXPECT_TRUE(encode_request(read_request(FunctionCode::read_holding_registers, 0, 125)).ok());
    expect_request_rejected(read_request(FunctionCode::read_holding_registers, 0, 126),
                            "FC3 request: quantity 126 outside 1..125");
    expect_request_rejected(read_request(FunctionCode::read_input_registers, 0, 0),
                            "quantity 0 outside 1..125");
}

TEST(PduEncodeRequest, WriteQuantityLimits) {
    EXPECT_TRUE(encode_request(write_multiple_coils(0, repeated(1968, 1))).ok());
    expect_request_rejected(write_multiple_coils(0, repeated(1969, 1)),
                            "FC15 request: quantity 1969 outside 1..1968");
    expect_request_rejected(write_multiple_coils(0, {}), "quantity 0 outside 1..1968");
    EXPECT_TRUE(encode_request(write_multiple_registers(0, repeated(123, 7))).ok());
    expect_request_rejected(write_multiple_registers(0, repeated(124, 7)),
                            "FC16 request: quantity 124 outside 1..123");
    expect_request_rejected(write_multiple_registers(0, {}), "quantity 0 outside 1..123");
}

TEST(PduEncodeRequest, MaximalWritesFillTheByteCount) {
    const auto coils = encode_request(write_multiple_coils(0, repeated(1968, 1))).value();
    EXPECT_EQ(coils[5], 246);  // ceil(1968 / 8)
    EXPECT_EQ(coils.size(), 6u + 246u);
    const auto registers = encode_request(write_multiple_registers(0, repeated(123, 7))).value();
    EXPECT_EQ(registers[5], 246);  // 2 * 123
    EXPECT_EQ(registers.size(), 6u + 246u);
}

TEST(PduEncodeRequest, AddressRangeMustStayBelowFFFFh) {
    EXPECT_TRUE(encode_request(read_request(FunctionCode::read_holding_registers, 0xFFFF, 1)).ok());
    EXPECT_TRUE(encode_request(read_request(FunctionCode::read_holding_registers, 0xFF83, 125)).ok());
    expect_request_rejected(read_request(FunctionCode::read_holding_registers, 0xFFFF, 2),
                            "address 65535 + quantity 2 runs past FFFFh");
    expect_request_rejected(read_request(FunctionCode::read_coils, 0xFF00, 257), "runs past FFFFh");
    expect_request_rejected(write_multiple_registers(0xFFFE, {1, 2, 3}), "runs past FFFFh");
    expect_request_rejected(write_multiple_coils(0xFFFF, {1, 0}), "runs past FFFFh");
    // A single write addresses one item: FFFFh itself is fine.
    EXPECT_TRUE(encode_request(write_single_register(0xFFFF, 1)).ok());
}

TEST(PduEncodeRequest, CoilStatesMustBeZeroOrOne) {
    expect_request_rejected(write_multiple_coils(0, {0, 1, 2}), "bit state 2 at index 2 is not 0 or 1");
    expect_request_rejected(Request{5, 10, 1, {7}}, "bit state 7");
}

TEST(PduEncodeRequest, InconsistentRequestsAreUsageErrors) {
    expect_request_rejected(Request{3, 0, 2, {1, 2}}, "a read carries no values");
    expect_request_rejected(Request{6, 0, 1, {}}, "exactly one value");
    expect_request_rejected(Request{6, 0, 2, {1, 2}}, "exactly one value");
    expect_request_rejected(Request{16, 0, 3, {1, 2}}, "count 3 differs from the 2 values given");
}

TEST(PduEncodeRequest, UnsupportedFunctionNamesTheCode) {
    expect_request_rejected(Request{43, 0, 1, {}}, "unsupported function code 43");
    expect_request_rejected(Request{0, 0, 1, {}}, "unsupported function code 0");
}

// ---- request decoding -----------------------------------------------------------------------

TEST(PduDecodeRequest, RoundTripsEveryFunction) {
    const std::vector<Request> requests{
        read_request(FunctionCode::read_coils, 201, 14),
        read_request(FunctionCode::read_discrete_inputs, 0, 2000),
        read_request(FunctionCode::read_holding_registers, 178, 3),
        read_request(FunctionCode::read_input_registers, 0xFF83, 125),
        write_single_coil(219, true),
        write_single_coil(0, false),
        write_single_register(2006, 1250),
        write_multiple_coils(224, {0, 1, 1, 0, 1, 0, 1, 1, 1}),
        write_multiple_coils(0, repeated(1968, 1)),
        write_multiple_registers(139, {300, 0x8000, 700}),
        write_multiple_registers(1, repeated(123, 0xBEEF)),
    };
    for (const Request& request : requests) {
        const auto pdu = encode_request(request);
        ASSERT_TRUE(pdu.ok()) << pdu.error().message;
        const auto decoded = decode_request(pdu.value());
        ASSERT_TRUE(decoded.ok()) << decoded.error().message;
        EXPECT_EQ(decoded.value(), request) << "function " << int{request.function};
    }
}

TEST(PduDecodeRequest, FieldsOfTheAc20Fc15Example) {
    const auto request = decode_request(hex("0F 00 E0 00 09 02 D6 01")).value();
    EXPECT_EQ(request.function, 15);
    EXPECT_EQ(request.address, 224);
    EXPECT_EQ(request.count, 9);
    EXPECT_THAT(request.values, ElementsAre(0, 1, 1, 0, 1, 0, 1, 1, 1));
}

TEST(PduDecodeRequest, PaddingBitsAreIgnored) {
    // V1.1b3 6.11 asks for zero padding, but a receiver has nothing to gain by refusing it.
    const auto request = decode_request(hex("0F 00 E0 00 09 02 D6 FF")).value();
    EXPECT_THAT(request.values, ElementsAre(0, 1, 1, 0, 1, 0, 1, 1, 1));
}

TEST(PduDecodeRequest, WriteSingleCoilAcceptsOnlyFF00AndZero) {
    EXPECT_EQ(decode_request(hex("05 00 DB FF 00")).value(), write_single_coil(219, true));
    EXPECT_EQ(decode_request(hex("05 00 DB 00 00")).value(), write_single_coil(219, false));
    expect_request_pdu_malformed("05 00 DB 00 01",
                                 "FC5 request: coil value 0001h is neither 0000h (off) nor FF00h (on)");
    expect_request_pdu_malformed("05 00 DB 12 34", "coil value 1234h");
    expect_request_pdu_malformed("05 00 DB FF FF", "coil value FFFFh");
}

TEST(PduDecodeRequest, ByteCountMustMatchQuantity) {
    expect_request_pdu_malformed("10 00 8B 00 03 05 01 2C 80 00 02",
                                 "FC16 request: byte count 5 does not match quantity 3 (expected 6)");
    expect_request_pdu_malformed("0F 00 E0 00 09 01 D6",
                                 "FC15 request: byte count 1 does not match quantity 9 (expected 2)");
    expect_request_pdu_malformed("0F 00 E0 00 09 03 D6 01 00",
                                 "byte count 3 does not match quantity 9 (expected 2)");
}

TEST(PduDecodeRequest, ExactLengthRejectsTrailingAndMissingBytes) {
    expect_request_pdu_malformed("03 00 B2 00 03 00", "FC3 request: 6 bytes, expected 5");
    expect_request_pdu_malformed("03 00 B2 00", "FC3 request: 4 bytes, expected 5");
    expect_request_pdu_malformed("01", "FC1 request: 1 byte, expected 5");
    expect_request_pdu_malformed("06 07 D6 04 E2 00", "FC6 request: 6 bytes, expected 5");
    expect_request_pdu_malformed("05 00 DB FF", "FC5 request: 4 bytes, expected 5");
    expect_request_pdu_malformed("10 00 8B 00 03 06 01 2C 80 00 02 BC 00",
                                 "FC16 request: 13 bytes, expected 12 (6 + byte count 6)");
    expect_request_pdu_malformed("10 00 8B 00 03 06 01 2C 80 00 02", "FC16 request: 11 bytes, expected 12");
    expect_request_pdu_malformed("0F 00 E0 00 09", "FC15 request: 5 bytes, too short for the 6-byte header");
}

TEST(PduDecodeRequest, QuantityLimits) {
    expect_request_pdu_malformed("01 00 00 00 00", "FC1 request: quantity 0 outside 1..2000");
    expect_request_pdu_malformed("02 00 00 07 D1", "FC2 request: quantity 2001 outside 1..2000");
    expect_request_pdu_malformed("03 00 00 00 7E", "FC3 request: quantity 126 outside 1..125");
    expect_request_pdu_malformed("04 00 00 00 00", "FC4 request: quantity 0 outside 1..125");
    expect_request_pdu_malformed("0F 00 00 00 00 00", "FC15 request: quantity 0 outside 1..1968");
    expect_request_pdu_malformed("10 00 00 00 7C F8", "FC16 request: quantity 124 outside 1..123");
}

TEST(PduDecodeRequest, AddressRange) {
    EXPECT_TRUE(decode_request(hex("03 FF FF 00 01")).ok());
    expect_request_pdu_malformed("03 FF FF 00 02", "FC3 request: address 65535 + quantity 2 runs past FFFFh");
    expect_request_pdu_malformed("10 FF FF 00 02 04 00 01 00 02", "runs past FFFFh");
}

TEST(PduDecodeRequest, UnknownAndEmpty) {
    expect_request_pdu_malformed("2B 0E 01 00", "unsupported function code 43");
    expect_request_pdu_malformed("83 03", "unsupported function code 131");
    expect_request_pdu_malformed("", "empty request PDU");
}

// ---- replies --------------------------------------------------------------------------------

TEST(PduDecodeReply, ReadBitsGivesWholeBytesOfBits) {
    // AC20 "Function code 1 and 2" example reply: byte count 2, A7h 04h. The reply does not
    // say 14 bits were asked for, so all 16 come back; match_reply trims.
    const Reply reply = decoded_reply("01 02 A7 04");
    EXPECT_EQ(reply.function, 1);
    EXPECT_EQ(reply.kind, ReplyKind::normal);
    EXPECT_EQ(reply.count, 16);
    EXPECT_THAT(reply.values, ElementsAre(1, 1, 1, 0, 0, 1, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0));
}

TEST(PduDecodeReply, ReadRegistersAc20Example) {
    // AC20 "Function code 3 and 4" example: FF9Ch (-100), 8000h (not implemented), 055Ah (1370).
    const Reply reply = decoded_reply("03 06 FF 9C 80 00 05 5A");
    EXPECT_EQ(reply.function, 3);
    EXPECT_EQ(reply.count, 3);
    EXPECT_THAT(reply.values, ElementsAre(0xFF9C, 0x8000, 0x055A));
    EXPECT_EQ(static_cast<std::int16_t>(reply.values[0]), -100);
}

TEST(PduDecodeReply, WriteEchoes) {
    const Reply coil = decoded_reply("05 00 DB FF 00");
    EXPECT_EQ(coil.address, 219);
    EXPECT_THAT(coil.values, ElementsAre(1));
    const Reply coil_off = decoded_reply("05 00 DB 00 00");
    EXPECT_THAT(coil_off.values, ElementsAre(0));
    const Reply word = decoded_reply("06 07 D6 04 E2");
    EXPECT_EQ(word.address, 2006);
    EXPECT_THAT(word.values, ElementsAre(1250));
    const Reply coils = decoded_reply("0F 00 E0 00 09");
    EXPECT_EQ(coils.address, 224);
    EXPECT_EQ(coils.count, 9);
    EXPECT_TRUE(coils.values.empty());
    const Reply registers = decoded_reply("10 00 8B 00 03");
    EXPECT_EQ(registers.address, 139);
    EXPECT_EQ(registers.count, 3);
}

TEST(PduDecodeReply, ExceptionReplies) {
    // Ramp/soak manual §4.7.1: 83h 03h = exception to FC3, illegal data value.
    const Reply reply = decoded_reply("83 03");
    EXPECT_EQ(reply.kind, ReplyKind::exception);
    EXPECT_EQ(reply.function, 3);
    EXPECT_EQ(reply.exception_code, 3);
    EXPECT_EQ(reply, exception_reply(3, 3));
    // Device-specific codes (AC20 "Error reply": 101..208) are kept as numbers.
    EXPECT_EQ(decoded_reply("90 65"), exception_reply(16, 101));
    // An exception to a function loopwire does not support is still a valid answer.
    EXPECT_EQ(decoded_reply("AB 01"), exception_reply(43, 1));
}

TEST(PduDecodeReply, ExceptionRepliesHaveExactlyTwoBytes) {
    expect_reply_pdu_malformed("83", "exception reply to function 3: 1 byte, expected 2");
    expect_reply_pdu_malformed("83 03 00", "exception reply to function 3: 3 bytes, expected 2");
    expect_reply_pdu_malformed("80 01", "function 0");
}

TEST(PduDecodeReply, ReadReplyByteCountValidation) {
    expect_reply_pdu_malformed("03 05 00 01 00 02 00",
                               "FC3 reply: byte count 5 is not an even number in 2..250");
    expect_reply_pdu_malformed("03 00", "FC3 reply: byte count 0 is not an even number in 2..250");
    expect_reply_pdu_malformed("01 00", "FC1 reply: byte count 0 is not in 1..250");
    expect_reply_pdu_malformed("03", "FC3 reply: 1 byte, too short");
}

TEST(PduDecodeReply, ReadReplyLargestByteCounts) {
    Bytes registers{0x04, 250};
    registers.resize(252, 0x11);
    EXPECT_EQ(decode_reply(registers).value().values.size(), 125u);
    Bytes too_many{0x04, 252};
    too_many.resize(254, 0x11);
    expect_reply_pdu_malformed(to_hex(too_many), "byte count 252 is not an even number in 2..250");
    Bytes bits{0x02, 250};
    bits.resize(252, 0xFF);
    EXPECT_EQ(decode_reply(bits).value().values.size(), 2000u);
}

TEST(PduDecodeReply, ExactLength) {
    expect_reply_pdu_malformed("03 06 FF 9C 80 00 05", "FC3 reply: 7 bytes, expected 8 (2 + byte count 6)");
    expect_reply_pdu_malformed("03 06 FF 9C 80 00 05 5A 00", "FC3 reply: 9 bytes, expected 8");
    expect_reply_pdu_malformed("01 02 A7", "FC1 reply: 3 bytes, expected 4");
    expect_reply_pdu_malformed("06 07 D6 04 E2 00", "FC6 reply: 6 bytes, expected 5");
    expect_reply_pdu_malformed("10 00 8B 00", "FC16 reply: 4 bytes, expected 5");
}

TEST(PduDecodeReply, WriteReplyValidation) {
    expect_reply_pdu_malformed("05 00 DB 00 FF", "FC5 reply: coil value 00FFh is neither");
    expect_reply_pdu_malformed("0F 00 E0 00 00", "FC15 reply: quantity 0 outside 1..1968");
    expect_reply_pdu_malformed("10 00 00 00 7C", "FC16 reply: quantity 124 outside 1..123");
    expect_reply_pdu_malformed("10 FF FF 00 02", "FC16 reply: address 65535 + quantity 2 runs past FFFFh");
}

TEST(PduDecodeReply, UnknownAndEmpty) {
    expect_reply_pdu_malformed("11 05 01 02 03 04 05", "unsupported function code 17");
    expect_reply_pdu_malformed("", "empty reply PDU");
}

TEST(PduEncodeReply, NormalReplies) {
    Reply bits{1, ReplyKind::normal, 0, 0, 0, {1, 1, 1, 0, 0, 1, 0, 1, 0, 0, 1, 0, 0, 0}};
    EXPECT_EQ(encode_reply(bits).value(), hex("01 02 A7 04"));
    Reply registers{3, ReplyKind::normal, 0, 0, 0, {0xFF9C, 0x8000, 0x055A}};
    EXPECT_EQ(encode_reply(registers).value(), hex("03 06 FF 9C 80 00 05 5A"));
    Reply coil{5, ReplyKind::normal, 0, 219, 1, {1}};
    EXPECT_EQ(encode_reply(coil).value(), hex("05 00 DB FF 00"));
    Reply word{6, ReplyKind::normal, 0, 2006, 1, {1250}};
    EXPECT_EQ(encode_reply(word).value(), hex("06 07 D6 04 E2"));
    Reply coils{15, ReplyKind::normal, 0, 224, 9, {}};
    EXPECT_EQ(encode_reply(coils).value(), hex("0F 00 E0 00 09"));
    Reply words{16, ReplyKind::normal, 0, 139, 3, {}};
    EXPECT_EQ(encode_reply(words).value(), hex("10 00 8B 00 03"));
}

TEST(PduEncodeReply, ExceptionReplies) {
    // Ramp/soak manual §4.7.3: 90h 02h, illegal register address to FC16.
    EXPECT_EQ(encode_reply(exception_reply(16, 2)).value(), hex("90 02"));
    EXPECT_EQ(encode_reply(exception_reply(43, 1)).value(), hex("AB 01"));
    EXPECT_EQ(encode_reply(exception_reply(0, 1)).error().kind, ErrorKind::usage);
    EXPECT_EQ(encode_reply(exception_reply(0x83, 1)).error().kind, ErrorKind::usage);
}

TEST(PduEncodeReply, InvalidRepliesAreUsageErrors) {
    const auto too_many = encode_reply(Reply{3, ReplyKind::normal, 0, 0, 0, repeated(126, 1)});
    EXPECT_THAT(too_many.error().message, HasSubstr("FC3 reply: 126 values, outside 1..125"));
    EXPECT_EQ(too_many.error().kind, ErrorKind::usage);
    EXPECT_THAT(encode_reply(Reply{1, ReplyKind::normal, 0, 0, 0, {}}).error().message,
                HasSubstr("FC1 reply: 0 values, outside 1..2000"));
    EXPECT_THAT(encode_reply(Reply{2, ReplyKind::normal, 0, 0, 0, {1, 3}}).error().message,
                HasSubstr("bit state 3"));
    EXPECT_THAT(encode_reply(Reply{5, ReplyKind::normal, 0, 0, 1, {2}}).error().message,
                HasSubstr("bit state 2"));
    EXPECT_THAT(encode_reply(Reply{6, ReplyKind::normal, 0, 0, 1, {}}).error().message,
                HasSubstr("exactly one value"));
    EXPECT_THAT(encode_reply(Reply{16, ReplyKind::normal, 0, 0, 0, {}}).error().message,
                HasSubstr("FC16 reply: quantity 0 outside 1..123"));
    EXPECT_THAT(encode_reply(Reply{17, ReplyKind::normal, 0, 0, 0, {}}).error().message,
                HasSubstr("unsupported function code 17"));
}

TEST(PduEncodeReply, RoundTrips) {
    const std::vector<Reply> replies{
        Reply{3, ReplyKind::normal, 0, 0, 3, {1, 2, 3}},
        Reply{4, ReplyKind::normal, 0, 0, 125, repeated(125, 0xA5A5)},
        Reply{1, ReplyKind::normal, 0, 0, 16, {1, 0, 1, 0, 1, 0, 1, 0, 1, 1, 1, 1, 0, 0, 0, 0}},
        Reply{5, ReplyKind::normal, 0, 7, 1, {0}},
        Reply{6, ReplyKind::normal, 0, 7, 1, {0xFFFF}},
        Reply{15, ReplyKind::normal, 0, 100, 1968, {}},
        Reply{16, ReplyKind::normal, 0, 100, 123, {}},
        exception_reply(4, 2),
    };
    for (const Reply& reply : replies) {
        const auto pdu = encode_reply(reply);
        ASSERT_TRUE(pdu.ok()) << pdu.error().message;
        const auto decoded = decode_reply(pdu.value());
        ASSERT_TRUE(decoded.ok()) << decoded.error().message;
        EXPECT_EQ(decoded.value(), reply) << "function " << int{reply.function};
    }
}

// ---- expected_pdu_length --------------------------------------------------------------------

TEST(PduExpectedLength, EmptyPrefixNeedsMoreBytes) {
    EXPECT_EQ(expected_pdu_length(Direction::request, {}), std::nullopt);
    EXPECT_EQ(expected_pdu_length(Direction::reply, {}), std::nullopt);
}

TEST(PduExpectedLength, Requests) {
    for (std::uint8_t fc = 1; fc <= 6; ++fc) {
        EXPECT_EQ(expected_pdu_length(Direction::request, Bytes{fc}), 5u) << int{fc};
    }
    EXPECT_EQ(expected_pdu_length(Direction::request, hex("10 00 8B 00 03")), std::nullopt);
    EXPECT_EQ(expected_pdu_length(Direction::request, hex("10 00 8B 00 03 06")), 12u);
    EXPECT_EQ(expected_pdu_length(Direction::request, hex("0F 00 E0 00 09 02 D6")), 8u);
    EXPECT_EQ(expected_pdu_length(Direction::request, hex("0F")), std::nullopt);
    // Exceptions only travel slave to master: as a request 83h is just an unknown function.
    EXPECT_EQ(expected_pdu_length(Direction::request, hex("83 03")), 0u);
    EXPECT_EQ(expected_pdu_length(Direction::request, hex("2B 0E")), 0u);
}

TEST(PduExpectedLength, Replies) {
    EXPECT_EQ(expected_pdu_length(Direction::reply, hex("03")), std::nullopt);
    EXPECT_EQ(expected_pdu_length(Direction::reply, hex("03 06")), 8u);
    EXPECT_EQ(expected_pdu_length(Direction::reply, hex("01 02 A7")), 4u);
    EXPECT_EQ(expected_pdu_length(Direction::reply, hex("02 FF")), 257u);  // the framer rejects it
    EXPECT_EQ(expected_pdu_length(Direction::reply, hex("04 02")), 4u);
    for (std::uint8_t fc : std::initializer_list<std::uint8_t>{5, 6, 15, 16}) {
        EXPECT_EQ(expected_pdu_length(Direction::reply, Bytes{fc}), 5u) << int{fc};
    }
    EXPECT_EQ(expected_pdu_length(Direction::reply, hex("83")), 2u);
    EXPECT_EQ(expected_pdu_length(Direction::reply, hex("90")), 2u);
    EXPECT_EQ(expected_pdu_length(Direction::reply, hex("AB")), 2u);
    EXPECT_EQ(expected_pdu_length(Direction::reply, hex("11")), 0u);
    EXPECT_EQ(expected_pdu_length(Direction::reply, hex("00")), 0u);
}

// ---- match_reply ----------------------------------------------------------------------------

TEST(PduMatchReply, BitsAreTrimmedToTheRequestedCount) {
    // AC20 "Function code 1 and 2": 14 bits asked for, 2 bytes (16 bits) returned.
    const Request request = read_request(FunctionCode::read_coils, 201, 14);
    const auto matched = match_reply(request, decoded_reply("01 02 A7 04"));
    ASSERT_TRUE(matched.ok()) << matched.error().message;
    EXPECT_EQ(matched->count, 14);
    EXPECT_EQ(matched->address, 201);
    EXPECT_THAT(matched->values, ElementsAre(1, 1, 1, 0, 0, 1, 0, 1, 0, 0, 1, 0, 0, 0));
}

TEST(PduMatchReply, BitByteCountMustFitTheQuantity) {
    const Request request = read_request(FunctionCode::read_coils, 201, 14);
    expect_mismatch(request, decoded_reply("01 01 A7"),
                    "FC1 reply: byte count 1 does not match quantity 14 (expected 2)");
    expect_mismatch(request, decoded_reply("01 03 A7 04 00"),
                    "byte count 3 does not match quantity 14 (expected 2)");
}

TEST(PduMatchReply, RegisterCountMustMatch) {
    const Request request = read_request(FunctionCode::read_holding_registers, 178, 3);
    const auto matched = match_reply(request, decoded_reply("03 06 FF 9C 80 00 05 5A"));
    ASSERT_TRUE(matched.ok());
    EXPECT_EQ(matched->address, 178);
    EXPECT_EQ(matched->count, 3);
    expect_mismatch(request, decoded_reply("03 04 FF 9C 80 00"),
                    "FC3 reply: byte count 4 does not match quantity 3 (expected 6)");
}

TEST(PduMatchReply, FunctionMustMatch) {
    const Request request = read_request(FunctionCode::read_holding_registers, 178, 3);
    expect_mismatch(request, decoded_reply("04 06 FF 9C 80 00 05 5A"),
                    "reply is for function 4 (read input registers), the request was function 3 "
                    "(read holding registers)");
    expect_mismatch(request, exception_reply(4, 2), "reply is for function 4");
}

TEST(PduMatchReply, ExceptionsForTheSameFunctionPass) {
    const Request request = read_request(FunctionCode::read_holding_registers, 138, 1);
    const auto matched = match_reply(request, decoded_reply("83 03"));
    ASSERT_TRUE(matched.ok());
    EXPECT_EQ(matched->kind, ReplyKind::exception);
    EXPECT_EQ(matched->exception_code, 3);
}

TEST(PduMatchReply, SingleWriteEchoes) {
    EXPECT_TRUE(match_reply(write_single_coil(219, true), decoded_reply("05 00 DB FF 00")).ok());
    expect_mismatch(write_single_coil(219, true), decoded_reply("05 00 DC FF 00"),
                    "FC5 reply: address echo 220 differs from the 219 requested");
    expect_mismatch(write_single_coil(219, true), decoded_reply("05 00 DB 00 00"),
                    "FC5 reply: value echo 0 differs from the 1 requested");
    EXPECT_TRUE(match_reply(write_single_register(2006, 1250), decoded_reply("06 07 D6 04 E2")).ok());
    expect_mismatch(write_single_register(2006, 1250), decoded_reply("06 07 D6 04 E3"),
                    "FC6 reply: value echo 1251 differs from the 1250 requested");
}

TEST(PduMatchReply, MultipleWriteEchoes) {
    const Request coils = write_multiple_coils(224, {0, 1, 1, 0, 1, 0, 1, 1, 1});
    EXPECT_TRUE(match_reply(coils, decoded_reply("0F 00 E0 00 09")).ok());
    expect_mismatch(coils, decoded_reply("0F 00 E0 00 08"),
                    "FC15 reply: quantity echo 8 differs from the 9 requested");
    const Request words = write_multiple_registers(139, {300, 0x8000, 700});
    EXPECT_TRUE(match_reply(words, decoded_reply("10 00 8B 00 03")).ok());
    expect_mismatch(words, decoded_reply("10 00 8A 00 03"),
                    "FC16 reply: address echo 138 differs from the 139 requested");
}

}  // namespace
}  // namespace loopwire::codec

namespace loopwire::codec {
namespace {

// What a request reads and what it writes (Modbus application protocol V1.1b3, 6.1-6.17): the
// serial master tells a copy of a read's reply from before a write over it by these.
TEST(DataSpansRead, NameTheirTableAddressAndQuantity) {
    const auto holding = read_span(Bytes{0x03, 0x03, 0x09, 0x00, 0x02});
    ASSERT_TRUE(holding.has_value());
    EXPECT_EQ(holding->table, Table::holding_registers);
    EXPECT_EQ(holding->first, 777);
    EXPECT_EQ(holding->count, 2u);
    EXPECT_EQ(read_span(Bytes{0x01, 0x00, 0x10, 0x00, 0x08})->table, Table::coils);
    EXPECT_EQ(read_span(Bytes{0x02, 0x00, 0x10, 0x00, 0x08})->table, Table::discrete_inputs);
    EXPECT_EQ(read_span(Bytes{0x04, 0x00, 0x10, 0x00, 0x08})->table, Table::input_registers);
    EXPECT_FALSE(read_span(Bytes{0x06, 0x00, 0x10, 0x00, 0x08}).has_value());
    EXPECT_FALSE(read_span(Bytes{0x03, 0x00}).has_value()) << "too short to say";
}

TEST(DataSpansWritten, NameWhatEachWritingFunctionChanges) {
    const auto spans = [](Bytes pdu) { return written_span(pdu); };
    EXPECT_EQ(spans({0x05, 0x00, 0x07, 0xFF, 0x00})->table, Table::coils);
    EXPECT_EQ(spans({0x06, 0x03, 0x09, 0x00, 0x05})->count, 1u);
    const auto multiple = spans({0x10, 0x00, 0x0A, 0x00, 0x03, 0x06, 0, 1, 0, 2, 0, 3});
    ASSERT_TRUE(multiple.has_value());
    EXPECT_EQ(multiple->first, 10);
    EXPECT_EQ(multiple->count, 3u);
    EXPECT_EQ(spans({0x0F, 0x00, 0x0A, 0x00, 0x0C, 0x02, 0xFF, 0x0F})->count, 12u);
    EXPECT_EQ(spans({0x16, 0x00, 0x04, 0x00, 0xF2, 0x00, 0x25})->first, 4);
    const auto read_write = spans({0x17, 0x00, 0x03, 0x00, 0x06, 0x00, 0x0E, 0x00, 0x03, 0x06, 0, 0, 0, 0, 0, 0});
    ASSERT_TRUE(read_write.has_value());
    EXPECT_EQ(read_write->first, 14) << "the write part of 23";
    EXPECT_EQ(read_write->count, 3u);
    EXPECT_FALSE(spans({0x08, 0x00, 0x01, 0x00, 0x00}).has_value()) << "a function that may change anything";
}

TEST(DataSpansWritten, OverlapOnlyInOneTableAndSharedAddresses) {
    const DataSpan asked{Table::holding_registers, 10, 5};  // 10-14
    EXPECT_TRUE(asked.overlaps({Table::holding_registers, 14, 1}));
    EXPECT_TRUE(asked.overlaps({Table::holding_registers, 8, 3}));
    EXPECT_FALSE(asked.overlaps({Table::holding_registers, 15, 1}));
    EXPECT_FALSE(asked.overlaps({Table::holding_registers, 0, 10}));
    EXPECT_FALSE(asked.overlaps({Table::coils, 10, 5}));
    const DataSpan top{Table::holding_registers, 65535, 1};
    EXPECT_TRUE(top.overlaps({Table::holding_registers, 65530, 10}));
}

}  // namespace
}  // namespace loopwire::codec
