// Modbus ASCII framing: the ramp/soak controller manual's chapter 5 frames as named vectors,
// then encoder and streaming-decoder behaviour (Modbus over serial line V1.02, 2.5.2).
#include "codec/ascii.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/test_bytes.hpp"

#include <string>
#include <string_view>

namespace loopwire::codec {
namespace {

using loopwire::testing::hex;

using ::testing::HasSubstr;
using namespace std::string_view_literals;

Bytes chars(std::string_view text) { return Bytes(text.begin(), text.end()); }

// One decode of `wire` that must yield exactly one event.
FrameEvent decode_one(std::string_view wire, unsigned data_bits = 8) {
    AsciiDecoder decoder(data_bits);
    FrameEvents events = decoder.feed(chars(wire));
    EXPECT_EQ(events.size(), 1u) << wire;
    if (events.empty()) return DiscardedBytes{{}, "no event"};
    return events.front();
}

Frame expect_frame(const FrameEvent& event) {
    if (const auto* discarded = std::get_if<DiscardedBytes>(&event)) {
        ADD_FAILURE() << "discarded: " << discarded->reason;
        return {};
    }
    return std::get<Frame>(event);
}

DiscardedBytes expect_discarded(const FrameEvent& event) {
    if (std::holds_alternative<Frame>(event)) {
        ADD_FAILURE() << "decoded a frame where a discard was expected";
        return {};
    }
    return std::get<DiscardedBytes>(event);
}

// A manual example: decodes to `unit` + `pdu`, its LRC is the printed one, and encoding the
// decoded frame gives back the very characters the manual prints.
void expect_manual_frame(std::string_view wire, std::uint8_t unit, std::string_view pdu_hex,
                         std::uint8_t printed_lrc) {
    const Frame frame = expect_frame(decode_one(wire));
    EXPECT_EQ(frame.unit, unit);
    EXPECT_EQ(frame.pdu, hex(pdu_hex));
    EXPECT_EQ(frame.raw, chars(wire));
    EXPECT_EQ(frame.transaction, 0);

    Bytes summed{unit};
    const Bytes pdu = hex(pdu_hex);
    summed.insert(summed.end(), pdu.begin(), pdu.end());
    EXPECT_EQ(lrc(summed), printed_lrc);
    EXPECT_EQ(ascii_encode(unit, pdu), chars(wire));
}

// --- Ramp/soak controller manual, chapter 5 --------------------------------------------

TEST(AsciiManualFrames, RampSoak_5_7_ReadPvRequestLrc71) {
    expect_manual_frame(":0103008A000171\r\n", 0x01, "03 00 8A 00 01", 0x71);
}

TEST(AsciiManualFrames, RampSoak_5_7_ReadPvReplyLrc0F) {
    expect_manual_frame(":01030203E80F\r\n", 0x01, "03 02 03 E8", 0x0F);
}

TEST(AsciiManualFrames, RampSoak_5_7_ReadPvExceptionLrc79) {
    expect_manual_frame(":01830379\r\n", 0x01, "83 03", 0x79);
}

// §5.7.1 prints the same characters for the request and its echo reply.
TEST(AsciiManualFrames, RampSoak_5_7_1_Fc06RequestAndEchoLrc95) {
    expect_manual_frame(":01060000006495\r\n", 0x01, "06 00 00 00 64", 0x95);
}

TEST(AsciiManualFrames, RampSoak_5_7_1_Fc06ExceptionLrc76) {
    expect_manual_frame(":01860376\r\n", 0x01, "86 03", 0x76);
}

TEST(AsciiManualFrames, RampSoak_5_7_2_Fc16RequestLrc9A) {
    expect_manual_frame(":01100000000204006403E89A\r\n", 0x01, "10 00 00 00 02 04 00 64 03 E8", 0x9A);
}

TEST(AsciiManualFrames, RampSoak_5_7_2_Fc16ReplyLrcED) {
    expect_manual_frame(":011000000002ED\r\n", 0x01, "10 00 00 00 02", 0xED);
}

// The RTU version of this frame has a wrong printed CRC (AUDIT.md); the ASCII one is right
// for function 90h.
TEST(AsciiManualFrames, RampSoak_5_7_2_Fc16ExceptionLrc6D) {
    expect_manual_frame(":0190026D\r\n", 0x01, "90 02", 0x6D);
}

// --- LRC and encoding ------------------------------------------------------------------

TEST(AsciiLrc, IsTwosComplementOfByteSum) {
    EXPECT_EQ(lrc(Bytes{}), 0x00);
    EXPECT_EQ(lrc(Bytes{0x01}), 0xFF);
    EXPECT_EQ(lrc(Bytes{0x80, 0x80}), 0x00);           // the sum wraps at 8 bits
    EXPECT_EQ(lrc(Bytes{0xFF, 0xFF, 0x03}), 0xFF);     // 0x201 -> 01h -> FFh
    const Bytes bytes = hex("11 03 00 6B 00 03");    // Modbus serial line V1.02 example
    EXPECT_EQ(lrc(bytes), 0x7E);
}

TEST(AsciiLrc, AddsUpToZeroWithTheBytes) {
    Bytes bytes;
    for (int i = 0; i < 300; ++i) {
        bytes.push_back(static_cast<std::uint8_t>(i * 37 + 5));
        std::uint8_t total = lrc(bytes);
        for (std::uint8_t b : bytes) total = static_cast<std::uint8_t>(total + b);
        ASSERT_EQ(total, 0) << "after " << bytes.size() << " bytes";
    }
}

TEST(AsciiEncode, UsesUpperCaseHexAndCrLf) {
    EXPECT_EQ(ascii_encode(0xAB, hex("CD EF 0A")), chars(":ABCDEF0A8F\r\n"));
}

TEST(AsciiEncode, EmptyPduStillCarriesUnitAndLrc) {
    EXPECT_EQ(ascii_encode(0x01, Bytes{}), chars(":01FF\r\n"));
}

// --- Decoding: accepted variants -------------------------------------------------------

TEST(AsciiDecode, LowerCaseHexIsAccepted) {
    const Frame frame = expect_frame(decode_one(":0103008a000171\r\n"));
    EXPECT_EQ(frame.pdu, hex("03 00 8A 00 01"));
    EXPECT_EQ(frame.raw, chars(":0103008a000171\r\n"));  // raw keeps what came off the wire
}

TEST(AsciiDecode, MixedCaseHexIsAccepted) {
    const Frame frame = expect_frame(decode_one(":01100000000204006403e89a\r\n"));
    EXPECT_EQ(frame.pdu, hex("10 00 00 00 02 04 00 64 03 E8"));
}

TEST(AsciiDecode, ShortestFrameIsUnitFunctionLrc) {
    const Frame frame = expect_frame(decode_one(":0101FE\r\n"));
    EXPECT_EQ(frame.unit, 0x01);
    EXPECT_EQ(frame.pdu, hex("01"));
}

TEST(AsciiDecode, LongestFrameCarriesA253BytePdu) {
    Bytes pdu(253);
    for (std::size_t i = 0; i < pdu.size(); ++i) pdu[i] = static_cast<std::uint8_t>(i);
    const Bytes wire = ascii_encode(0x11, pdu);
    ASSERT_EQ(wire.size(), 513u);  // the serial-line spec's maximum ASCII frame
    AsciiDecoder decoder;
    const FrameEvents events = decoder.feed(wire);
    ASSERT_EQ(events.size(), 1u);
    const Frame frame = expect_frame(events[0]);
    EXPECT_EQ(frame.unit, 0x11);
    EXPECT_EQ(frame.pdu, pdu);
}

TEST(AsciiDecode, RoundTripsEveryPduSizeAndSeveralUnits) {
    for (std::uint8_t unit : std::initializer_list<std::uint8_t>{0x00, 0x01, 0x7F, 0xF7, 0xFF}) {
        for (std::size_t size = 1; size <= 253; ++size) {
            Bytes pdu(size);
            for (std::size_t i = 0; i < size; ++i) pdu[i] = static_cast<std::uint8_t>(i * 53 + unit + size);
            AsciiDecoder decoder;
            const FrameEvents events = decoder.feed(ascii_encode(unit, pdu));
            ASSERT_EQ(events.size(), 1u) << "unit " << int(unit) << " size " << size;
            const Frame frame = expect_frame(events[0]);
            ASSERT_EQ(frame.unit, unit);
            ASSERT_EQ(frame.pdu, pdu);
        }
    }
}

// Some adapters set up for 7 data bits hand the parity bit over in bit 7.
TEST(AsciiDecode, SevenDataBitsIgnoreTheEighthBit) {
    Bytes wire = chars(":01030203E80F\r\n");
    for (std::size_t i = 0; i < wire.size(); i += 2) wire[i] |= 0x80;
    AsciiDecoder decoder(7);
    const FrameEvents events = decoder.feed(wire);
    ASSERT_EQ(events.size(), 1u);
    const Frame frame = expect_frame(events[0]);
    EXPECT_EQ(frame.pdu, hex("03 02 03 E8"));
    EXPECT_EQ(frame.raw, chars(":01030203E80F\r\n"));  // the characters as interpreted
}

TEST(AsciiDecode, EightDataBitsKeepTheEighthBit) {
    Bytes wire = chars(":01030203E80F\r\n");
    wire[3] |= 0x80;  // '0' of the function code becomes B0h
    const DiscardedBytes discarded = expect_discarded(decode_one(
        std::string_view(reinterpret_cast<const char*>(wire.data()), wire.size())));
    EXPECT_THAT(discarded.reason, HasSubstr("non-hex character B0h at position 3"));
}

// --- Decoding: stream handling ---------------------------------------------------------

TEST(AsciiDecode, FrameSplitIntoSingleBytes) {
    const Bytes wire = chars(":01100000000204006403E89A\r\n");
    AsciiDecoder decoder;
    FrameEvents events;
    for (std::size_t i = 0; i < wire.size(); ++i) {
        FrameEvents got = decoder.feed(ByteView(wire).subspan(i, 1));
        if (i + 1 < wire.size()) {
            EXPECT_TRUE(got.empty()) << "event after byte " << i;
        }
        events.insert(events.end(), got.begin(), got.end());
    }
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(expect_frame(events[0]).pdu, hex("10 00 00 00 02 04 00 64 03 E8"));
}

TEST(AsciiDecode, FrameSplitBetweenCrAndLf) {
    AsciiDecoder decoder;
    EXPECT_TRUE(decoder.feed(chars(":0103008A000171\r")).empty());
    const FrameEvents events = decoder.feed(chars("\n"));
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(expect_frame(events[0]).raw, chars(":0103008A000171\r\n"));
}

TEST(AsciiDecode, SeveralFramesInOneFeed) {
    AsciiDecoder decoder;
    const FrameEvents events =
        decoder.feed(chars(":0103008A000171\r\n:01030203E80F\r\n:01830379\r\n:0106"));
    ASSERT_EQ(events.size(), 3u);
    EXPECT_EQ(expect_frame(events[0]).pdu, hex("03 00 8A 00 01"));
    EXPECT_EQ(expect_frame(events[1]).pdu, hex("03 02 03 E8"));
    EXPECT_EQ(expect_frame(events[2]).pdu, hex("83 03"));
    // The fourth frame completes in the next read.
    const FrameEvents rest = decoder.feed(chars("0000006495\r\n"));
    ASSERT_EQ(rest.size(), 1u);
    EXPECT_EQ(expect_frame(rest[0]).pdu, hex("06 00 00 00 64"));
}

TEST(AsciiDecode, ColonInsidePartialFrameDiscardsItAndStartsAgain) {
    AsciiDecoder decoder;
    const FrameEvents events = decoder.feed(chars(":01030:0103008A000171\r\n"));
    ASSERT_EQ(events.size(), 2u);
    const DiscardedBytes discarded = expect_discarded(events[0]);
    EXPECT_EQ(discarded.bytes, chars(":01030"));
    EXPECT_THAT(discarded.reason, HasSubstr("new ':' before CR LF"));
    EXPECT_EQ(expect_frame(events[1]).pdu, hex("03 00 8A 00 01"));
}

TEST(AsciiDecode, ColonAcrossFeedsDiscardsThePartialFrame) {
    AsciiDecoder decoder;
    EXPECT_TRUE(decoder.feed(chars(":0103008A00")).empty());
    const FrameEvents events = decoder.feed(chars(":01830379\r\n"));
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(expect_discarded(events[0]).bytes, chars(":0103008A00"));
    EXPECT_EQ(expect_frame(events[1]).pdu, hex("83 03"));
}

// Noise is reported once per run, when the ':' that ends the run arrives.
TEST(AsciiDecode, NoiseBeforeAFrameIsOneEventWhenColonArrives) {
    AsciiDecoder decoder;
    EXPECT_TRUE(decoder.feed(chars("xy\x00z"sv)).empty());
    EXPECT_TRUE(decoder.feed(chars("\xFF" "abc")).empty());
    const FrameEvents events = decoder.feed(chars(":01830379\r\n"));
    ASSERT_EQ(events.size(), 2u);
    const DiscardedBytes noise = expect_discarded(events[0]);
    EXPECT_EQ(noise.bytes, chars("xy\x00z\xFF" "abc"sv));
    EXPECT_THAT(noise.reason, HasSubstr("outside a frame"));
    EXPECT_EQ(expect_frame(events[1]).pdu, hex("83 03"));
}

TEST(AsciiDecode, NoiseBetweenFramesIsReported) {
    AsciiDecoder decoder;
    const FrameEvents events = decoder.feed(chars(":01830379\r\n~~~:01860376\r\n"));
    ASSERT_EQ(events.size(), 3u);
    EXPECT_EQ(expect_frame(events[0]).pdu, hex("83 03"));
    EXPECT_EQ(expect_discarded(events[1]).bytes, chars("~~~"));
    EXPECT_EQ(expect_frame(events[2]).pdu, hex("86 03"));
}

// Decision: CR and LF on an idle line are line ends, not noise. Inside a run of real noise
// they are reported with it, so the run is shown as it arrived.
TEST(AsciiDecode, IdleLineEndsAloneAreNotNoise) {
    AsciiDecoder decoder;
    const FrameEvents events = decoder.feed(chars("\r\n\n\r:01830379\r\n\r\n:01860376\r\n"));
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(expect_frame(events[0]).pdu, hex("83 03"));
    EXPECT_EQ(expect_frame(events[1]).pdu, hex("86 03"));
}

TEST(AsciiDecode, LineEndsInsideNoiseAreReportedWithIt) {
    AsciiDecoder decoder;
    const FrameEvents events = decoder.feed(chars("\r\nAT\r\nOK\r\n:01830379\r\n"));
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(expect_discarded(events[0]).bytes, chars("\r\nAT\r\nOK\r\n"));
    EXPECT_EQ(expect_frame(events[1]).pdu, hex("83 03"));
}

TEST(AsciiDecode, BareLfDoesNotEndAFrame) {
    AsciiDecoder decoder;
    EXPECT_TRUE(decoder.feed(chars(":01830379\n")).empty());
    const FrameEvents events = decoder.feed(chars(":01830379\r\n"));
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(expect_discarded(events[0]).bytes, chars(":01830379\n"));
    EXPECT_EQ(expect_frame(events[1]).pdu, hex("83 03"));
}

TEST(AsciiDecode, ResetDropsPartialFrameAndNoise) {
    AsciiDecoder decoder;
    EXPECT_EQ(decoder.feed(chars("junk:0103008A")).size(), 1u);  // the junk, at the ':'
    decoder.reset();
    // Without the ':' the rest of the old frame is just noise now.
    EXPECT_TRUE(decoder.feed(chars("000171\r\n")).empty());
    decoder.reset();
    const FrameEvents events = decoder.feed(chars(":01830379\r\n"));
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(expect_frame(events[0]).pdu, hex("83 03"));
}

// --- Decoding: every error path ----------------------------------------------------------

TEST(AsciiDecodeErrors, BadLrcNamesBothValues) {
    const DiscardedBytes discarded = expect_discarded(decode_one(":0103008A000172\r\n"));
    EXPECT_EQ(discarded.reason, "LRC mismatch: computed 71, received 72");
    EXPECT_EQ(discarded.bytes, chars(":0103008A000172\r\n"));
}

TEST(AsciiDecodeErrors, OddDigitCount) {
    const DiscardedBytes discarded = expect_discarded(decode_one(":0103008A00017\r\n"));
    EXPECT_THAT(discarded.reason, HasSubstr("odd number of hex digits (13)"));
}

TEST(AsciiDecodeErrors, NonHexCharacterNamesCharacterAndPosition) {
    const DiscardedBytes discarded = expect_discarded(decode_one(":0103008G000171\r\n"));
    EXPECT_THAT(discarded.reason, HasSubstr("non-hex character 'G' (47h) at position 8"));
}

TEST(AsciiDecodeErrors, SpaceIsNotHex) {
    const DiscardedBytes discarded = expect_discarded(decode_one(":01 03008A000171\r\n"));
    EXPECT_THAT(discarded.reason, HasSubstr("' ' (20h) at position 3"));
}

TEST(AsciiDecodeErrors, CrInsideFrameIsNotHex) {
    const DiscardedBytes discarded = expect_discarded(decode_one(":01\r03008A000171\r\n"));
    EXPECT_THAT(discarded.reason, HasSubstr("non-hex character 0Dh at position 3"));
}

TEST(AsciiDecodeErrors, TooShortFrames) {
    for (std::string_view wire : {":\r\n", ":01\r\n", ":0103\r\n"}) {
        const DiscardedBytes discarded = expect_discarded(decode_one(wire));
        EXPECT_THAT(discarded.reason, HasSubstr("frame too short")) << wire;
        EXPECT_EQ(discarded.bytes, chars(wire));
    }
}

TEST(AsciiDecodeErrors, TooLongFrameIsCutAtTheLimitAndTheTailIsNoise) {
    // 512 hex characters would already be a 254-byte PDU, one byte more than Modbus allows.
    const std::string body(600, '0');
    AsciiDecoder decoder;
    const FrameEvents events = decoder.feed(chars(":" + body + "\r\n:01830379\r\n"));
    ASSERT_EQ(events.size(), 3u);
    const DiscardedBytes too_long = expect_discarded(events[0]);
    EXPECT_THAT(too_long.reason, HasSubstr("frame too long"));
    EXPECT_EQ(too_long.bytes.size(), 1u + 512u);  // ':' and every character up to the cut
    const DiscardedBytes tail = expect_discarded(events[1]);
    EXPECT_THAT(tail.reason, HasSubstr("outside a frame"));
    // Built with append, not operator+ on a temporary: GCC 12 reports a false -Warray-bounds on
    // std::string(n, c) + "..." when optimising (GCC bug 105651).
    std::string expected_tail(600 - 512, '0');
    expected_tail.append("\r\n");
    EXPECT_EQ(tail.bytes, chars(expected_tail));
    EXPECT_EQ(expect_frame(events[2]).pdu, hex("83 03"));
}

TEST(AsciiDecodeErrors, FiveHundredElevenHexCharactersAreTooLong) {
    const std::string body(511, 'F');
    AsciiDecoder decoder;
    const FrameEvents events = decoder.feed(chars(":" + body + "\r\n"));
    ASSERT_EQ(events.size(), 1u);
    EXPECT_THAT(expect_discarded(events[0]).reason, HasSubstr("frame too long"));
}

// Hostile input never makes the decoder hold, or report, more than one frame's worth.
TEST(AsciiDecodeErrors, EndlessInputKeepsEveryEventBounded) {
    AsciiDecoder decoder;
    const std::string no_colon(100000, 'x');
    const FrameEvents noise = decoder.feed(chars(no_colon));
    std::size_t reported = 0;
    for (const FrameEvent& event : noise) {
        const DiscardedBytes discarded = expect_discarded(event);
        EXPECT_LE(discarded.bytes.size(), 513u);
        reported += discarded.bytes.size();
    }
    EXPECT_GE(reported, 100000u - 513u);

    const std::string no_crlf = ":" + std::string(100000, 'A');
    for (const FrameEvent& event : decoder.feed(chars(no_crlf))) {
        EXPECT_LE(expect_discarded(event).bytes.size(), 513u);
    }
}

}  // namespace
}  // namespace loopwire::codec
