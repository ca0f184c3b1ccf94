// Modbus TCP framing: MBAP header layout, stream reassembly and the header checks that make a
// connection unusable (Modbus Messaging on TCP/IP V1.0b, 3.1.3).
#include "codec/tcp.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/test_bytes.hpp"

#include <string_view>

namespace loopwire::codec {
namespace {

using loopwire::testing::hex;
using loopwire::testing::concat;

using ::testing::HasSubstr;

// The ramp/soak manual's FC3 exchange (§4.7.1) carried over TCP instead of RTU.
const Bytes read_pv_pdu = hex("03 00 8A 00 01");
const Bytes read_pv_adu = hex("00 2A 00 00 00 06 01 03 00 8A 00 01");

std::vector<Frame> feed_ok(MbapDecoder& decoder, ByteView bytes) {
    auto result = decoder.feed(bytes);
    EXPECT_TRUE(result.ok()) << (result.ok() ? "" : result.error().message);
    return result.ok() ? std::move(result).value() : std::vector<Frame>{};
}

Error feed_error(MbapDecoder& decoder, ByteView bytes) {
    auto result = decoder.feed(bytes);
    EXPECT_FALSE(result.ok());
    return result.ok() ? make_error(ErrorKind::usage, "no error") : result.error();
}

TEST(MbapEncode, HeaderIsTransactionProtocolZeroLengthUnit) {
    EXPECT_EQ(mbap_encode(0x002A, 0x01, read_pv_pdu), read_pv_adu);
    EXPECT_EQ(mbap_encode(0xFFFF, 0xFF, hex("83 02")), hex("FF FF 00 00 00 03 FF 83 02"));
}

TEST(MbapEncode, LengthCountsUnitAndPdu) {
    const Bytes pdu(253, 0x10);
    const Bytes adu = mbap_encode(1, 1, pdu);
    ASSERT_EQ(adu.size(), 7u + 253u);
    EXPECT_EQ(read_be16(adu, 4), 254);
}

TEST(MbapDecode, OneFrame) {
    MbapDecoder decoder;
    const std::vector<Frame> frames = feed_ok(decoder, read_pv_adu);
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].transaction, 0x002A);
    EXPECT_EQ(frames[0].unit, 0x01);
    EXPECT_EQ(frames[0].pdu, read_pv_pdu);
    EXPECT_EQ(frames[0].raw, read_pv_adu);
    EXPECT_EQ(decoder.buffered(), 0u);
}

TEST(MbapDecode, RoundTripsEveryPduSize) {
    for (std::size_t size = 1; size <= 253; ++size) {
        Bytes pdu(size);
        for (std::size_t i = 0; i < size; ++i) pdu[i] = static_cast<std::uint8_t>(i + size);
        const auto transaction = static_cast<std::uint16_t>(size * 257);
        MbapDecoder decoder;
        const std::vector<Frame> frames = feed_ok(decoder, mbap_encode(transaction, 0x11, pdu));
        ASSERT_EQ(frames.size(), 1u) << size;
        EXPECT_EQ(frames[0].transaction, transaction);
        EXPECT_EQ(frames[0].unit, 0x11);
        EXPECT_EQ(frames[0].pdu, pdu);
    }
}

TEST(MbapDecode, ShortestFrameIsUnitAndFunctionCode) {
    MbapDecoder decoder;
    const std::vector<Frame> frames = feed_ok(decoder, hex("00 01 00 00 00 02 07 11"));
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].pdu, hex("11"));
}

TEST(MbapDecode, PartialReadsByteByByte) {
    MbapDecoder decoder;
    for (std::size_t i = 0; i + 1 < read_pv_adu.size(); ++i) {
        EXPECT_TRUE(feed_ok(decoder, ByteView(read_pv_adu).subspan(i, 1)).empty()) << i;
        EXPECT_EQ(decoder.buffered(), i + 1);
    }
    const std::vector<Frame> frames = feed_ok(decoder, ByteView(read_pv_adu).last(1));
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].pdu, read_pv_pdu);
    EXPECT_EQ(decoder.buffered(), 0u);
}

TEST(MbapDecode, SplitInsideTheHeader) {
    MbapDecoder decoder;
    EXPECT_TRUE(feed_ok(decoder, ByteView(read_pv_adu).first(5)).empty());
    const std::vector<Frame> frames = feed_ok(decoder, ByteView(read_pv_adu).subspan(5));
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].transaction, 0x002A);
}

TEST(MbapDecode, SeveralFramesAndAPartialOneInOneRead) {
    const Bytes second = mbap_encode(0x002B, 0x02, hex("06 00 00 00 64"));
    const Bytes third = mbap_encode(0x002C, 0x03, hex("10 00 00 00 02 04 00 64 03 E8"));
    MbapDecoder decoder;
    const Bytes stream = concat({read_pv_adu, second, third});
    const std::vector<Frame> frames = feed_ok(decoder, ByteView(stream).first(stream.size() - 4));
    ASSERT_EQ(frames.size(), 2u);
    EXPECT_EQ(frames[0].transaction, 0x002A);
    EXPECT_EQ(frames[1].transaction, 0x002B);
    EXPECT_EQ(frames[1].unit, 0x02);
    EXPECT_EQ(frames[1].raw, second);
    EXPECT_EQ(decoder.buffered(), third.size() - 4);

    const std::vector<Frame> rest = feed_ok(decoder, ByteView(stream).last(4));
    ASSERT_EQ(rest.size(), 1u);
    EXPECT_EQ(rest[0].transaction, 0x002C);
    EXPECT_EQ(rest[0].pdu, hex("10 00 00 00 02 04 00 64 03 E8"));
}

TEST(MbapDecode, EmptyFeedIsHarmless) {
    MbapDecoder decoder;
    EXPECT_TRUE(feed_ok(decoder, Bytes{}).empty());
    EXPECT_EQ(decoder.buffered(), 0u);
}

TEST(MbapDecodeErrors, NonZeroProtocolIdNamesFieldAndValue) {
    MbapDecoder decoder;
    const Error error = feed_error(decoder, hex("00 01 12 34 00 06 01 03 00 8A 00 01"));
    EXPECT_EQ(error.kind, ErrorKind::malformed);
    EXPECT_THAT(error.message, HasSubstr("MBAP protocol id 1234h (4660)"));
    EXPECT_THAT(error.message, HasSubstr("close the connection"));
}

// The protocol id is refused as soon as its two bytes are in, not after a whole "frame".
TEST(MbapDecodeErrors, ProtocolIdRefusedOnItsFourthByte) {
    MbapDecoder decoder;
    EXPECT_TRUE(feed_ok(decoder, hex("47 45 54")).empty());
    const Error error = feed_error(decoder, hex("20"));  // "GET " from an HTTP client
    EXPECT_THAT(error.message, HasSubstr("protocol id 5420h"));
}

TEST(MbapDecodeErrors, LengthBelowTwoNamesFieldAndValue) {
    for (std::uint16_t length : std::initializer_list<std::uint16_t>{0, 1}) {
        MbapDecoder decoder;
        Bytes header = hex("00 01 00 00");
        append_be16(header, length);
        const Error error = feed_error(decoder, header);
        EXPECT_EQ(error.kind, ErrorKind::malformed);
        EXPECT_THAT(error.message, HasSubstr("MBAP length " + std::to_string(length) + " is outside 2..260"));
    }
}

TEST(MbapDecodeErrors, LengthAbove260NamesFieldAndValue) {
    for (std::uint16_t length : std::initializer_list<std::uint16_t>{261, 262, 0xFFFF}) {
        MbapDecoder decoder;
        Bytes header = hex("00 01 00 00");
        append_be16(header, length);
        const Error error = feed_error(decoder, header);
        EXPECT_THAT(error.message, HasSubstr("MBAP length " + std::to_string(length) + " is outside 2..260"));
    }
}

// A length of 255..260 is wrong (PDU past 253 bytes) but still delimits the frame: it is handed
// out whole, so the receiver can refuse it and the next frame is read in step.
TEST(MbapDecode, OverlongPduWithATrustedLengthIsFramedByItsLength) {
    for (std::uint16_t length : std::initializer_list<std::uint16_t>{255, 260}) {
        Bytes overlong = hex("00 05 00 00");
        append_be16(overlong, length);
        overlong.push_back(0x01);
        overlong.push_back(0x10);
        overlong.resize(6u + length, 0x00);
        MbapDecoder decoder;
        const std::vector<Frame> frames = feed_ok(decoder, concat({overlong, read_pv_adu}));
        ASSERT_EQ(frames.size(), 2u) << length;
        EXPECT_EQ(frames[0].transaction, 5);
        EXPECT_EQ(frames[0].pdu.size(), length - 1u);
        EXPECT_EQ(frames[0].pdu[0], 0x10);
        EXPECT_EQ(frames[1].pdu, read_pv_pdu);
        EXPECT_FALSE(decoder.broken());
    }
}

TEST(MbapDecodeErrors, LongestLegalLengthIsAccepted) {
    MbapDecoder decoder;
    const std::vector<Frame> frames = feed_ok(decoder, mbap_encode(7, 1, Bytes(253, 0xAA)));
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].pdu.size(), 253u);
}

// A bad header cannot be skipped on a byte stream, but the frames before it in the same read
// are complete requests: they come out, broken() names the error, and the error is sticky
// until reset().
TEST(MbapDecodeErrors, FramesBeforeABadHeaderComeOutAndTheErrorIsSticky) {
    MbapDecoder decoder;
    const std::vector<Frame> good = feed_ok(decoder, concat({read_pv_adu, hex("00 02 00 01 00 06")}));
    ASSERT_EQ(good.size(), 1u);
    EXPECT_EQ(good[0].pdu, read_pv_pdu);
    ASSERT_TRUE(decoder.broken());
    EXPECT_THAT(decoder.broken()->message, HasSubstr("protocol id 0001h"));
    EXPECT_EQ(decoder.buffered(), 6u);  // the good frame before it was consumed
    const Error again = feed_error(decoder, read_pv_adu);
    EXPECT_EQ(again.message, decoder.broken()->message);

    decoder.reset();
    EXPECT_EQ(decoder.buffered(), 0u);
    EXPECT_FALSE(decoder.broken());
    EXPECT_EQ(feed_ok(decoder, read_pv_adu).size(), 1u);
}

TEST(MbapDecodeErrors, ABadHeaderAloneIsAnError) {
    MbapDecoder decoder;
    const Error error = feed_error(decoder, hex("00 02 00 01 00 06"));
    EXPECT_THAT(error.message, HasSubstr("protocol id 0001h"));
    ASSERT_TRUE(decoder.broken());
}

}  // namespace
}  // namespace loopwire::codec
