// The ramp/soak controller's Linking protocol (its manual, chapter 6): the manual's frames as
// named vectors, the sum rule, every decode error and the resynchronising stream decoder.
#include "codec/linking.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/test_bytes.hpp"

#include <string_view>

namespace loopwire::codec {
namespace {

using loopwire::testing::hex;
using loopwire::testing::concat;

using ::testing::HasSubstr;

std::string request_error(std::string_view frame_hex) {
    const auto result = decode_linking_request(hex(frame_hex));
    EXPECT_FALSE(result.ok()) << frame_hex;
    if (result.ok()) return {};
    EXPECT_EQ(result.error().kind, ErrorKind::malformed);
    return result.error().message;
}

std::string reply_error(std::string_view frame_hex) {
    const auto result = decode_linking_reply(hex(frame_hex));
    EXPECT_FALSE(result.ok()) << frame_hex;
    if (result.ok()) return {};
    EXPECT_EQ(result.error().kind, ErrorKind::malformed);
    return result.error().message;
}

// The manual's frames (AUDIT.md lists them with their sums recomputed).
const Bytes read_pv_request = hex("52 01 00 8A 00 00 DD");     // §6.6 EX and §6.7.1
const Bytes read_pv_reply = hex("07 4D 01 00 8A 03 E8 C3");    // §6.7.1
const Bytes modify_sv_request = hex("4D 01 00 00 00 64 B2");   // §6.7.2
const Bytes write_sv_request = hex("57 01 00 00 03 E8 43");    // §6.7.3

// --- Ramp/soak controller manual, chapter 6 --------------------------------------------

TEST(LinkingManualFrames, RampSoak_6_6_ChecksumExampleDD) {
    // "52H + 01H + 00H + 8AH + 00H + 00H = DDH"
    EXPECT_EQ(linking_sum(hex("52 01 00 8A 00 00")), 0xDD);
}

TEST(LinkingManualFrames, RampSoak_6_7_1_ReadPvRequestSumDD) {
    const auto request = decode_linking_request(read_pv_request);
    ASSERT_TRUE(request.ok()) << request.error().message;
    EXPECT_EQ(request->command, LinkingCommand::read);
    EXPECT_EQ(request->id, 1);
    EXPECT_EQ(request->address, 0x008A);
    EXPECT_EQ(request->data, 0x0000);
    EXPECT_EQ(encode_linking_request(*request), read_pv_request);
}

// The reply's sum leaves the 07h header out: with it the sum would be CAh.
TEST(LinkingManualFrames, RampSoak_6_7_1_ReadPvReplySumC3ExcludesHeader) {
    const auto reply = decode_linking_reply(read_pv_reply);
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(reply->id, 1);
    EXPECT_EQ(reply->address, 0x008A);
    EXPECT_EQ(reply->data, 1000);  // PV = 100.0
    EXPECT_EQ(encode_linking_reply(*reply), read_pv_reply);
    EXPECT_EQ(linking_sum(hex("4D 01 00 8A 03 E8")), 0xC3);
    EXPECT_EQ(linking_sum(hex("07 4D 01 00 8A 03 E8")), 0xCA);
}

TEST(LinkingManualFrames, RampSoak_6_7_2_ModifyRamRequestSumB2) {
    const auto request = decode_linking_request(modify_sv_request);
    ASSERT_TRUE(request.ok()) << request.error().message;
    EXPECT_EQ(request->command, LinkingCommand::modify_ram);
    EXPECT_EQ(request->id, 1);
    EXPECT_EQ(request->address, 0x0000);
    EXPECT_EQ(request->data, 100);  // SV = 10.0
    EXPECT_EQ(encode_linking_request(*request), modify_sv_request);
}

TEST(LinkingManualFrames, RampSoak_6_7_3_WriteEepromRequestSum43) {
    const auto request = decode_linking_request(write_sv_request);
    ASSERT_TRUE(request.ok()) << request.error().message;
    EXPECT_EQ(request->command, LinkingCommand::write_eeprom);
    EXPECT_EQ(request->id, 1);
    EXPECT_EQ(request->address, 0x0000);
    EXPECT_EQ(request->data, 1000);  // SV = 100.0
    EXPECT_EQ(encode_linking_request(*request), write_sv_request);
}

// --- Encoding ----------------------------------------------------------------------------

TEST(LinkingEncode, SumKeepsTheLowEightBits) {
    const LinkingRequest request{LinkingCommand::write_eeprom, 0xFF, 0xFFFF, 0xFFFF};
    // 57h + FFh * 5 = 552h -> 52h
    EXPECT_EQ(encode_linking_request(request), hex("57 FF FF FF FF FF 52"));
}

TEST(LinkingEncode, RequestsAndRepliesRoundTrip) {
    for (LinkingCommand command :
         {LinkingCommand::read, LinkingCommand::modify_ram, LinkingCommand::write_eeprom}) {
        for (std::uint16_t value : std::initializer_list<std::uint16_t>{0x0000, 0x0001, 0x00FF, 0x1234, 0xFFFF}) {
            const LinkingRequest request{command, static_cast<std::uint8_t>(value), value,
                                         static_cast<std::uint16_t>(~value)};
            const Bytes wire = encode_linking_request(request);
            ASSERT_EQ(wire.size(), linking_request_size);
            const auto decoded = decode_linking_request(wire);
            ASSERT_TRUE(decoded.ok()) << decoded.error().message;
            EXPECT_EQ(*decoded, request);

            const LinkingReply reply{static_cast<std::uint8_t>(value >> 8), value,
                                     static_cast<std::uint16_t>(value * 3)};
            const Bytes reply_wire = encode_linking_reply(reply);
            ASSERT_EQ(reply_wire.size(), linking_reply_size);
            const auto decoded_reply = decode_linking_reply(reply_wire);
            ASSERT_TRUE(decoded_reply.ok()) << decoded_reply.error().message;
            EXPECT_EQ(*decoded_reply, reply);
        }
    }
}

// --- Decoding errors name the bad part ---------------------------------------------------

TEST(LinkingDecodeErrors, RequestSize) {
    EXPECT_THAT(request_error("52 01 00 8A 00 00"), HasSubstr("size: 6 bytes, expected 7"));
    EXPECT_THAT(request_error("52 01 00 8A 00 00 DD 00"), HasSubstr("size: 8 bytes, expected 7"));
    EXPECT_THAT(request_error(""), HasSubstr("size: 0 bytes"));
}

TEST(LinkingDecodeErrors, RequestCommand) {
    // 41h + 01 + 00 + 8A = CCh: the sum is right, the command is not.
    EXPECT_EQ(request_error("41 01 00 8A 00 00 CC"),
              "Linking request command 41h is not R (52h), M (4Dh) or W (57h)");
    // A reply's header where a request was expected.
    EXPECT_THAT(request_error("07 4D 01 00 8A 03 E8"), HasSubstr("command 07h"));
}

TEST(LinkingDecodeErrors, RequestSum) {
    EXPECT_EQ(request_error("52 01 00 8A 00 00 DE"),
              "Linking request sum mismatch: computed DDh, received DEh");
}

TEST(LinkingDecodeErrors, ReplySize) {
    EXPECT_THAT(reply_error("07 4D 01 00 8A 03 E8"), HasSubstr("size: 7 bytes, expected 8"));
    EXPECT_THAT(reply_error("07 4D 01 00 8A 03 E8 C3 00"), HasSubstr("size: 9 bytes, expected 8"));
}

TEST(LinkingDecodeErrors, ReplyHeader) {
    EXPECT_EQ(reply_error("06 4D 01 00 8A 03 E8 C3"), "Linking reply header 06h, expected 07h");
}

TEST(LinkingDecodeErrors, ReplyCommand) {
    // §6.1: the reply carries 4Dh whatever the request's command was.
    EXPECT_EQ(reply_error("07 52 01 00 8A 03 E8 C8"), "Linking reply command 52h, expected 4Dh");
}

TEST(LinkingDecodeErrors, ReplySum) {
    // A reply summed with its header (the misreading §6.7.1 rules out).
    EXPECT_EQ(reply_error("07 4D 01 00 8A 03 E8 CA"),
              "Linking reply sum mismatch: computed C3h, received CAh");
}

// --- Streaming decoder -------------------------------------------------------------------

struct Collected {
    std::vector<Bytes> frames;
    std::vector<LinkingEvent> discards;
};

Collected collect(const std::vector<LinkingEvent>& events) {
    Collected out;
    for (const LinkingEvent& event : events) {
        EXPECT_NE(event.frame.has_value(), event.discarded.has_value()) << "exactly one of frame/discarded";
        if (event.frame) out.frames.push_back(*event.frame);
        if (event.discarded) {
            EXPECT_FALSE(event.reason.empty());
            out.discards.push_back(event);
        }
    }
    return out;
}

TEST(LinkingDecoder, RequestFedByteByByte) {
    LinkingDecoder decoder(false);
    for (std::size_t i = 0; i + 1 < write_sv_request.size(); ++i) {
        EXPECT_TRUE(decoder.feed(ByteView(write_sv_request).subspan(i, 1)).empty()) << i;
    }
    const Collected got = collect(decoder.feed(ByteView(write_sv_request).last(1)));
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0], write_sv_request);
    EXPECT_TRUE(got.discards.empty());
}

TEST(LinkingDecoder, ReplyFedByteByByte) {
    LinkingDecoder decoder(true);
    std::vector<LinkingEvent> events;
    for (std::uint8_t byte : read_pv_reply) {
        auto got = decoder.feed(Bytes{byte});
        events.insert(events.end(), got.begin(), got.end());
    }
    const Collected got = collect(events);
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0], read_pv_reply);
    EXPECT_TRUE(got.discards.empty());
}

TEST(LinkingDecoder, SeveralFramesInOneFeed) {
    LinkingDecoder decoder(false);
    const Collected got = collect(decoder.feed(concat({read_pv_request, modify_sv_request, write_sv_request})));
    ASSERT_EQ(got.frames.size(), 3u);
    EXPECT_EQ(got.frames[0], read_pv_request);
    EXPECT_EQ(got.frames[1], modify_sv_request);
    EXPECT_EQ(got.frames[2], write_sv_request);
    EXPECT_TRUE(got.discards.empty());
}

TEST(LinkingDecoder, PartialFrameWaitsForTheNextFeed) {
    LinkingDecoder decoder(true);
    const Bytes stream = concat({read_pv_reply, read_pv_reply});
    Collected got = collect(decoder.feed(ByteView(stream).first(11)));
    ASSERT_EQ(got.frames.size(), 1u);
    got = collect(decoder.feed(ByteView(stream).subspan(11)));
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0], read_pv_reply);
}

TEST(LinkingDecoder, NoiseBeforeRequestIsOneDiscardWithReason) {
    LinkingDecoder decoder(false);
    const Collected got = collect(decoder.feed(concat({hex("00 FF 13"), read_pv_request})));
    ASSERT_EQ(got.discards.size(), 1u);
    EXPECT_EQ(*got.discards[0].discarded, hex("00 FF 13"));
    EXPECT_THAT(got.discards[0].reason, HasSubstr("before a Linking command"));
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0], read_pv_request);
}

// A corrupted frame is thrown away byte by byte until a frame whose sum checks starts.
TEST(LinkingDecoder, ResynchronisesAfterACorruptedRequest) {
    Bytes corrupted = read_pv_request;
    corrupted[5] = 0x01;  // data 0001h, sum still DDh
    LinkingDecoder decoder(false);
    const Collected got = collect(decoder.feed(concat({corrupted, modify_sv_request})));
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0], modify_sv_request);
    ASSERT_EQ(got.discards.size(), 1u);
    EXPECT_EQ(*got.discards[0].discarded, corrupted);
    EXPECT_EQ(got.discards[0].reason, "sum mismatch: computed DEh, received DDh in 52 01 00 8A 00 01 DD");
}

// A command byte inside the broken frame starts a new candidate; each failed candidate is its
// own discard, so every reported run has one reason.
TEST(LinkingDecoder, CommandByteInsideNoiseStartsItsOwnCandidate) {
    const Bytes noise = hex("01 57 02 03");  // 57h looks like W
    LinkingDecoder decoder(false);
    const Collected got = collect(decoder.feed(concat({noise, write_sv_request})));
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0], write_sv_request);
    ASSERT_EQ(got.discards.size(), 2u);
    EXPECT_EQ(*got.discards[0].discarded, hex("01"));
    EXPECT_THAT(got.discards[0].reason, HasSubstr("before a Linking command"));
    EXPECT_EQ(*got.discards[1].discarded, hex("57 02 03"));
    EXPECT_THAT(got.discards[1].reason, HasSubstr("sum mismatch"));
}

TEST(LinkingDecoder, ReplyHeaderWithoutCommandIsNoise) {
    LinkingDecoder decoder(true);
    const Collected got = collect(decoder.feed(concat({hex("07 07 52 4D"), read_pv_reply})));
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0], read_pv_reply);
    ASSERT_EQ(got.discards.size(), 1u);
    EXPECT_EQ(*got.discards[0].discarded, hex("07 07 52 4D"));
    EXPECT_THAT(got.discards[0].reason, HasSubstr("before a Linking reply header (07h 4Dh)"));
}

TEST(LinkingDecoder, LoneReplyHeaderByteWaitsForTheNext) {
    LinkingDecoder decoder(true);
    EXPECT_TRUE(decoder.feed(hex("07")).empty());
    const Collected got = collect(decoder.feed(ByteView(read_pv_reply).subspan(1)));
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0], read_pv_reply);
}

TEST(LinkingDecoder, ReplyWithHeaderInsideTheSumIsResynchronisedPast) {
    LinkingDecoder decoder(true);
    const Collected got = collect(decoder.feed(concat({hex("07 4D 01 00 8A 03 E8 CA"), read_pv_reply})));
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0], read_pv_reply);
    ASSERT_EQ(got.discards.size(), 1u);
    EXPECT_THAT(got.discards[0].reason, HasSubstr("computed C3h, received CAh"));
}

TEST(LinkingDecoder, ResetDropsAPartialFrame) {
    LinkingDecoder decoder(false);
    EXPECT_TRUE(decoder.feed(ByteView(read_pv_request).first(4)).empty());
    decoder.reset();
    const Collected got = collect(decoder.feed(write_sv_request));
    ASSERT_EQ(got.frames.size(), 1u);
    EXPECT_EQ(got.frames[0], write_sv_request);
    EXPECT_TRUE(got.discards.empty());
}

// Whatever arrives, every byte is either in a frame, in a discard, or in the pending tail
// (shorter than one frame), and every frame reported decodes.
TEST(LinkingDecoder, EveryByteIsAccountedForUnderNoise) {
    for (bool replies : {false, true}) {
        Bytes stream;
        std::uint32_t state = 12345;
        for (int i = 0; i < 20000; ++i) {
            state = state * 1103515245u + 12345u;
            stream.push_back(static_cast<std::uint8_t>(state >> 16));
            if (i % 97 == 0) {
                const Bytes frame = replies ? read_pv_reply : modify_sv_request;
                stream.insert(stream.end(), frame.begin(), frame.end());
            }
        }
        LinkingDecoder decoder(replies);
        std::size_t accounted = 0;
        std::size_t frames = 0;
        for (std::size_t at = 0; at < stream.size(); at += 333) {
            const std::size_t n = std::min<std::size_t>(333, stream.size() - at);
            for (const LinkingEvent& event : decoder.feed(ByteView(stream).subspan(at, n))) {
                if (event.frame) {
                    ++frames;
                    accounted += event.frame->size();
                    const bool decodes = replies ? decode_linking_reply(*event.frame).ok()
                                                 : decode_linking_request(*event.frame).ok();
                    EXPECT_TRUE(decodes) << to_hex(*event.frame);
                }
                if (event.discarded) accounted += event.discarded->size();
            }
        }
        const std::size_t frame_size = replies ? linking_reply_size : linking_request_size;
        EXPECT_LE(accounted, stream.size());
        EXPECT_GT(accounted + frame_size, stream.size());
        EXPECT_GE(frames, 20000u / 97u - 5) << "embedded frames mostly found";
    }
}

}  // namespace
}  // namespace loopwire::codec
