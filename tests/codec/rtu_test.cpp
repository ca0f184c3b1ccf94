// RTU framing tests: CRC-16, encoding, character timing, the streaming decoder, and every RTU
// example frame printed in the manuals (../shared/manuals beside the repository, listed in
// tests/codec/data/manual-example-frames.json and audited in AUDIT.md §1).
#include "codec/rtu.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/test_bytes.hpp"

#include <fstream>
#include <nlohmann/json.hpp>
#include <string_view>

namespace loopwire::codec {
namespace {

using loopwire::testing::hex;
using loopwire::testing::concat;

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using namespace std::chrono_literals;

const Instant t0{};  // the decoder only compares instants, any origin will do

std::vector<Frame> frames_in(const FrameEvents& events) {
    std::vector<Frame> frames;
    for (const auto& event : events) {
        if (const auto* frame = std::get_if<Frame>(&event)) frames.push_back(*frame);
    }
    return frames;
}

std::vector<DiscardedBytes> discards_in(const FrameEvents& events) {
    std::vector<DiscardedBytes> discards;
    for (const auto& event : events) {
        if (const auto* discarded = std::get_if<DiscardedBytes>(&event)) discards.push_back(*discarded);
    }
    return discards;
}

void append(FrameEvents& to, FrameEvents more) {
    to.insert(to.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
}

// Low byte first on the wire (AC20 "Error check", TC10 §3.5).
std::uint16_t crc_as_sent(const Bytes& frame) {
    return static_cast<std::uint16_t>(frame[frame.size() - 2] | (frame[frame.size() - 1] << 8));
}

std::uint16_t crc_of_body(const Bytes& frame) { return crc16(ByteView(frame).first(frame.size() - 2)); }

CharacterTiming timing_9600() { return CharacterTiming{9600, 11}; }

// ---- CRC-16 ---------------------------------------------------------------------------------

TEST(RtuCrc, StandardCheckValue) {
    // CRC-16/MODBUS of the ASCII digits "123456789" is 4B37h (the catalogue check value).
    const std::string digits = "123456789";
    const Bytes bytes(digits.begin(), digits.end());
    EXPECT_EQ(crc16(bytes), 0x4B37);
}

TEST(RtuCrc, EmptyInputLeavesTheInitialValue) { EXPECT_EQ(crc16({}), 0xFFFF); }

TEST(RtuCrc, RampSoakSection45RegisterValue) {
    // Ramp/soak manual §4.5 computes register E0A5h for the §4.7.1 request and then swaps
    // the bytes (step ⑨), so it prints A5E0H: the wire order, A5 first.
    EXPECT_EQ(crc16(hex("01 03 00 8A 00 01")), 0xE0A5);
}

TEST(RtuEncode, AppendsCrcLowByteFirst) {
    EXPECT_EQ(rtu_encode(0x01, hex("03 00 8A 00 01")), hex("01 03 00 8A 00 01 A5 E0"));
    EXPECT_EQ(rtu_encode(0x64, hex("01 00 C9 00 0E")), hex("64 01 00 C9 00 0E 64 05"));
}

TEST(RtuEncode, EncodedFramesDecodeBack) {
    const Bytes pdu = encode_request(write_multiple_registers(0x10, {1, 2, 3, 4})).value();
    const Bytes wire = rtu_encode(17, pdu);
    RtuDecoder decoder(Direction::request, CharacterTiming{});
    const auto frames = frames_in(decoder.feed(wire, t0));
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].unit, 17);
    EXPECT_EQ(frames[0].pdu, pdu);
    EXPECT_EQ(frames[0].raw, wire);
    EXPECT_EQ(frames[0].transaction, 0);
}

// ---- character timing (Modbus over serial line V1.02, 2.5.1.1) --------------------------------

TEST(RtuTiming, At9600With11BitCharacters) {
    const CharacterTiming timing = timing_9600();
    EXPECT_EQ(timing.character_time(), 1146us);  // 11 / 9600 s = 1145.8 us, rounded up
    EXPECT_EQ(timing.t1_5(), 1719us);            // 1718.75 us
    EXPECT_EQ(timing.t3_5(), 4011us);            // 4010.4 us
}

TEST(RtuTiming, At9600With10BitCharacters) {
    const CharacterTiming timing{9600, 10};  // 8N1 (TC10 §1)
    EXPECT_EQ(timing.character_time(), 1042us);
    EXPECT_EQ(timing.t3_5(), 3646us);  // 3645.8 us
}

TEST(RtuTiming, At19200StillCharacterBased) {
    const CharacterTiming timing{19200, 11};
    EXPECT_EQ(timing.character_time(), 573us);
    EXPECT_EQ(timing.t1_5(), 860us);   // 859.4 us
    EXPECT_EQ(timing.t3_5(), 2006us);  // 2005.2 us
}

TEST(RtuTiming, Above19200FixedValues) {
    const CharacterTiming timing{38400, 11};  // ramp/soak default baud (§1)
    EXPECT_EQ(timing.character_time(), 287us);
    EXPECT_EQ(timing.t1_5(), 750us);
    EXPECT_EQ(timing.t3_5(), 1750us);
    EXPECT_EQ((CharacterTiming{115200, 10}.t3_5()), 1750us);
}

TEST(RtuTiming, ZeroBaudDoesNotDivideByZero) { EXPECT_GT((CharacterTiming{0, 11}.t3_5()), 0us); }

// ---- streaming decoder ------------------------------------------------------------------------

const Bytes read_pv_request = hex("01 03 00 8A 00 01 A5 E0");  // ramp/soak §4.7.1

TEST(RtuDecoder, WholeFrameInOneFeed) {
    RtuDecoder decoder(Direction::request, timing_9600());
    const auto events = decoder.feed(read_pv_request, t0);
    ASSERT_EQ(events.size(), 1u);
    const Frame& frame = std::get<Frame>(events[0]);
    EXPECT_EQ(frame.unit, 1);
    EXPECT_EQ(frame.pdu, hex("03 00 8A 00 01"));
    EXPECT_EQ(frame.raw, read_pv_request);
    EXPECT_EQ(decoder.buffered(), 0u);
    EXPECT_EQ(decoder.silence_deadline(), std::nullopt);
}

TEST(RtuDecoder, ByteByByteFeedingCompletesOnTheLastByte) {
    RtuDecoder decoder(Direction::request, timing_9600());
    Instant now = t0;
    for (std::size_t i = 0; i + 1 < read_pv_request.size(); ++i) {
        EXPECT_TRUE(decoder.feed(ByteView(read_pv_request).subspan(i, 1), now).empty()) << "byte " << i;
        EXPECT_EQ(decoder.buffered(), i + 1);
        now += 1146us;  // one character time apart: a continuous transmission
    }
    const auto events = decoder.feed(ByteView(read_pv_request).last(1), now);
    const auto frames = frames_in(events);
    ASSERT_EQ(events.size(), 1u);
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].raw, read_pv_request);
}

TEST(RtuDecoder, SeveralFramesInOneFeedSplitByLength) {
    // Back to back with no gap, as a pseudo-terminal delivers them.
    const Bytes fc16 = hex("0A 10 00 8B 00 03 06 01 2C 80 00 02 BC 33 00");  // AC20 FC16 example
    const Bytes fc05 = hex("23 05 00 DB FF 00 FA 83");                       // AC20 FC5 example
    const Bytes fc15 = hex("02 0F 00 E0 00 09 02 D6 01 78 4C");              // AC20 FC15 example
    RtuDecoder decoder(Direction::request, timing_9600());
    const auto events = decoder.feed(concat({fc16, read_pv_request, fc05, fc15}), t0);
    const auto frames = frames_in(events);
    ASSERT_EQ(events.size(), 4u);
    ASSERT_EQ(frames.size(), 4u);
    EXPECT_EQ(frames[0].raw, fc16);
    EXPECT_EQ(frames[1].raw, read_pv_request);
    EXPECT_EQ(frames[2].raw, fc05);
    EXPECT_EQ(frames[3].raw, fc15);
    EXPECT_EQ(decoder.buffered(), 0u);
}

TEST(RtuDecoder, RepliesSplitByLengthIncludingExceptions) {
    const Bytes fc01 = hex("64 01 02 A7 04 8E 07");              // AC20 FC1 example reply
    const Bytes fc03 = hex("1D 03 06 FF 9C 80 00 05 5A D7 0D");  // AC20 FC3 example reply
    const Bytes exception = hex("01 83 03 01 31");               // ramp/soak §4.7.1
    const Bytes fc16 = hex("01 10 00 00 00 02 41 C8");           // ramp/soak §4.7.3
    RtuDecoder decoder(Direction::reply, CharacterTiming{38400, 11});
    const auto frames = frames_in(decoder.feed(concat({fc01, exception, fc03, fc16}), t0));
    ASSERT_EQ(frames.size(), 4u);
    EXPECT_EQ(frames[0].raw, fc01);
    EXPECT_EQ(frames[1].raw, exception);
    EXPECT_EQ(frames[1].pdu, hex("83 03"));
    EXPECT_EQ(frames[2].raw, fc03);
    EXPECT_EQ(frames[3].raw, fc16);
}

TEST(RtuDecoder, FrameSplitAcrossFeedsWithoutGap) {
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(ByteView(read_pv_request).first(3), t0).empty());
    // 3 ms is less than t3.5 = 4011 us at 9600 baud: the frame continues.
    const auto frames = frames_in(decoder.feed(ByteView(read_pv_request).subspan(3), t0 + 3ms));
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].raw, read_pv_request);
}

TEST(RtuDecoder, GapOfExactlyT35DoesNotEndTheFrame) {
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(ByteView(read_pv_request).first(4), t0).empty());
    // V1.02 2.5.1.1: a frame ends after *more than* 3.5 character times of silence.
    const auto frames = frames_in(decoder.feed(ByteView(read_pv_request).subspan(4), t0 + 4011us));
    ASSERT_EQ(frames.size(), 1u);
}

TEST(RtuDecoder, NoiseBeforeAFrameIsOneDiscardEvent) {
    // 07 03 reads as "unit 7, FC3" whose 8-byte candidate fails the CRC; sliding one byte
    // gives "unit 3, FC1", which fails too; the next byte starts the real frame.
    const Bytes noise = hex("07 03");
    RtuDecoder decoder(Direction::request, timing_9600());
    const auto events = decoder.feed(concat({noise, read_pv_request}), t0);
    ASSERT_EQ(events.size(), 2u);
    const auto* discarded = std::get_if<DiscardedBytes>(&events[0]);
    ASSERT_NE(discarded, nullptr);
    EXPECT_EQ(discarded->bytes, noise);
    EXPECT_THAT(discarded->reason, HasSubstr("CRC mismatch: computed "));
    const auto* frame = std::get_if<Frame>(&events[1]);
    ASSERT_NE(frame, nullptr);
    EXPECT_EQ(frame->raw, read_pv_request);
}

TEST(RtuDecoder, NoiseFedByteByByteIsStillOneDiscardEvent) {
    const Bytes wire = concat({hex("07 03"), read_pv_request});
    RtuDecoder decoder(Direction::request, timing_9600());
    FrameEvents events;
    Instant now = t0;
    for (std::uint8_t byte : wire) {
        append(events, decoder.feed(Bytes{byte}, now));
        now += 1ms;
    }
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(std::get<DiscardedBytes>(events[0]).bytes, hex("07 03"));
    EXPECT_EQ(std::get<Frame>(events[1]).raw, read_pv_request);
}

TEST(RtuDecoder, DiscardReasonNamesComputedAndReceivedCrc) {
    // The AC20 FC1 request with its CRC zeroed: computed 64 05, received 00 00.
    RtuDecoder decoder(Direction::request, timing_9600());
    FrameEvents events = decoder.feed(hex("64 01 00 C9 00 0E 00 00"), t0);
    append(events, decoder.flush(t0 + 10ms));
    const auto discards = discards_in(events);
    ASSERT_EQ(discards.size(), 1u);
    EXPECT_EQ(discards[0].reason, "CRC mismatch: computed 64 05, received 00 00");
    EXPECT_EQ(discards[0].bytes, hex("64 01 00 C9 00 0E 00 00"));
    EXPECT_TRUE(frames_in(events).empty());
}

// A reader scheduled late sees a "gap" the wire never had; when the bytes on both sides complete
// a frame whose CRC checks, the frame is kept.
TEST(RtuDecoder, GapInsideAFrameWhoseCrcChecksIsTakenForReaderLatency) {
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(ByteView(read_pv_request).first(4), t0).empty());
    const auto events = decoder.feed(ByteView(read_pv_request).subspan(4), t0 + 10ms);
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(std::get<Frame>(events[0]).raw, read_pv_request);
    EXPECT_EQ(decoder.buffered(), 0u);
}

// The same after noise: the frame that starts after the noise straddles the late read.
TEST(RtuDecoder, NoiseThenAFrameStraddlingAReaderLatencyGapKeepsTheFrame) {
    RtuDecoder decoder(Direction::request, timing_9600());
    const Bytes noisy = concat({hex("FF 00 13"), read_pv_request});
    EXPECT_TRUE(decoder.feed(ByteView(noisy).first(6), t0).empty());
    const auto at_rest = decoder.feed(ByteView(noisy).subspan(6), t0 + 10ms);
    const auto at_silence = decoder.flush(t0 + 20ms);
    FrameEvents events = at_rest;
    events.insert(events.end(), at_silence.begin(), at_silence.end());
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(std::get<DiscardedBytes>(events[0]).bytes, hex("FF 00 13"));
    EXPECT_EQ(std::get<Frame>(events[1]).raw, read_pv_request);
}

// A loaded machine: the reader got a reply in three pieces, each after more than t3.5. No piece
// ends a frame the function code says is longer, so the reply is kept whole.
TEST(RtuDecoder, ReplyReadInThreeLatePiecesIsKept) {
    const Bytes reply = hex("03 03 02 00 00 C1 84");  // TC10 unit 3, one register = 0
    RtuDecoder decoder(Direction::reply, timing_9600());
    EXPECT_TRUE(decoder.feed(ByteView(reply).first(2), t0).empty());
    EXPECT_TRUE(decoder.feed(ByteView(reply).subspan(2, 4), t0 + 5ms).empty());
    EXPECT_EQ(decoder.buffered(), 6u);
    const auto events = decoder.feed(ByteView(reply).subspan(6), t0 + 10ms);
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(std::get<Frame>(events[0]).raw, reply);
}

// A silence the reader waited through itself ends a frame under way once it has lasted the
// patience a reader's batches need (20 ms): then the frame is discarded, and the late pieces
// rule above does not keep it alive.
TEST(RtuDecoder, FrameCutShortBySilenceTheReaderSawIsDiscarded) {
    const Bytes reply = hex("03 03 02 00 00 C1 84");
    RtuDecoder decoder(Direction::reply, timing_9600());
    EXPECT_TRUE(decoder.feed(ByteView(reply).first(2), t0).empty());
    EXPECT_TRUE(decoder.feed(ByteView(reply).subspan(2, 2), t0 + 5ms).empty());
    EXPECT_TRUE(decoder.flush(t0 + 10ms).empty());  // more than 3.5 characters, less than the patience
    EXPECT_EQ(decoder.silence_deadline(), t0 + 25ms);
    const auto at_silence = decoder.flush(t0 + 26ms);
    ASSERT_EQ(at_silence.size(), 1u);
    EXPECT_EQ(std::get<DiscardedBytes>(at_silence[0]).bytes, hex("03 03 02 00"));
    EXPECT_EQ(std::get<DiscardedBytes>(at_silence[0]).reason, "gap inside frame: silence after 4 of 7 bytes");
    EXPECT_EQ(decoder.buffered(), 0u);
}

// A frame of unknown length has only silence to end it: one followed after a gap by a known
// frame comes out whole, and so does the known frame.
TEST(RtuDecoder, FrameOfUnknownFunctionThenAFrameAfterAGapAreBothKept) {
    RtuDecoder decoder(Direction::request, timing_9600());
    const Bytes unknown = rtu_encode(1, hex("41 00"));  // function 41h gives no length
    EXPECT_TRUE(decoder.feed(unknown, t0).empty());
    FrameEvents events = decoder.feed(read_pv_request, t0 + 10ms);
    append(events, decoder.flush(t0 + 20ms));
    EXPECT_TRUE(discards_in(events).empty());
    const auto frames = frames_in(events);
    ASSERT_EQ(frames.size(), 2u);
    EXPECT_EQ(frames[0].raw, unknown);
    EXPECT_EQ(frames[1].raw, read_pv_request);
}

// The second half makes the frame's full length and its CRC fails: the gap was real.
TEST(RtuDecoder, FrameSplitByALongGapIsDiscarded) {
    const Bytes second_half = hex("00 02 A5 E0");  // does not complete a frame whose CRC checks
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(ByteView(read_pv_request).first(4), t0).empty());
    // 10 ms > t3.5: the first half is judged on its own and cannot be a frame.
    const auto at_second_half = decoder.feed(second_half, t0 + 10ms);
    ASSERT_EQ(at_second_half.size(), 1u);
    const auto& first_half = std::get<DiscardedBytes>(at_second_half[0]);
    EXPECT_EQ(first_half.bytes, hex("01 03 00 8A"));
    EXPECT_EQ(first_half.reason, "gap inside frame: silence after 4 of 8 bytes");
    // The second half waits for more (it starts like a request of unit 0: a frame under way),
    // then is judged once the reader's silence has outlasted the patience.
    EXPECT_EQ(decoder.buffered(), 4u);
    EXPECT_TRUE(decoder.flush(t0 + 20ms).empty());
    const auto at_flush = decoder.flush(t0 + 30ms);
    ASSERT_EQ(at_flush.size(), 1u);
    EXPECT_EQ(std::get<DiscardedBytes>(at_flush[0]).bytes, second_half);
    EXPECT_EQ(decoder.buffered(), 0u);
}

TEST(RtuDecoder, CrcCorruptedFrameThenGoodFrameAfterAGap) {
    const Bytes corrupted = hex("01 03 00 8A 00 01 00 00");
    RtuDecoder decoder(Direction::request, timing_9600());
    // The candidate fails; the slide lands on "unit 3, function 0", unknown, and no frame
    // follows yet: the dropped byte is held so the whole damaged frame becomes one run.
    EXPECT_TRUE(decoder.feed(corrupted, t0).empty());
    const auto events = decoder.feed(read_pv_request, t0 + 5ms);
    ASSERT_EQ(events.size(), 2u);
    const auto& discarded = std::get<DiscardedBytes>(events[0]);
    EXPECT_EQ(discarded.bytes, corrupted);  // one run for the whole damaged frame
    EXPECT_EQ(discarded.reason, "CRC mismatch: computed A5 E0, received 00 00");
    EXPECT_EQ(std::get<Frame>(events[1]).raw, read_pv_request);
}

TEST(RtuDecoder, CrcCorruptedFrameThenGoodFrameBackToBack) {
    const Bytes corrupted = hex("01 03 00 8A 00 01 00 00");
    RtuDecoder decoder(Direction::request, timing_9600());
    // No gap (pseudo-terminal, serial device server). After the bad candidate the slide lands
    // on "unit 3, function 0": unknown, but while resynchronising the decoder looks ahead for
    // a frame that checks, finds the good one and drops everything before it as one run.
    const auto events = decoder.feed(concat({corrupted, read_pv_request}), t0);
    ASSERT_EQ(events.size(), 2u);
    const auto& discarded = std::get<DiscardedBytes>(events[0]);
    EXPECT_EQ(discarded.bytes, corrupted);
    EXPECT_EQ(discarded.reason, "CRC mismatch: computed A5 E0, received 00 00");
    EXPECT_EQ(std::get<Frame>(events[1]).raw, read_pv_request);
    EXPECT_EQ(decoder.buffered(), 0u);
}

TEST(RtuDecoder, CorruptedReplyResynchronisesWithoutSilence) {
    // A damaged FC6 echo followed at once by a good one, on the master side.
    const Bytes good = hex("01 06 00 00 00 64 88 21");  // ramp/soak §4.7.2
    const Bytes damaged = hex("01 06 00 00 00 64 88 22");
    RtuDecoder decoder(Direction::reply, CharacterTiming{38400, 11});
    const auto events = decoder.feed(concat({damaged, good}), t0);
    ASSERT_EQ(events.size(), 2u);
    const auto& discarded = std::get<DiscardedBytes>(events[0]);
    EXPECT_EQ(discarded.bytes, damaged);
    EXPECT_EQ(discarded.reason, "CRC mismatch: computed 88 21, received 88 22");
    EXPECT_EQ(std::get<Frame>(events[1]).raw, good);
}

TEST(RtuDecoder, UnknownFunctionNoiseAtAFrameBoundaryWaitsForSilence) {
    // 00 FF reads as "unit 0, function 255": no length, and nothing was being resynchronised,
    // so the decoder waits for silence (it might be a genuine frame of an unknown function).
    // After the silence the bytes before the frame that checks are dropped.
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(concat({hex("00 FF"), read_pv_request}), t0).empty());
    const auto events = decoder.flush(t0 + 5ms);
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(std::get<DiscardedBytes>(events[0]).bytes, hex("00 FF"));
    EXPECT_EQ(std::get<Frame>(events[1]).raw, read_pv_request);
}

TEST(RtuDecoder, UnknownFunctionFrameFollowedBackToBackByAKnownOne) {
    // An FC17 request and an FC3 request with no gap: the FC17 frame has no length, so both
    // wait for silence; then the frame that checks further on marks where FC17 ended.
    const Bytes report_id = rtu_encode(0x05, hex("11"));
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(concat({report_id, read_pv_request}), t0).empty());
    const auto frames = frames_in(decoder.flush(t0 + 5ms));
    ASSERT_EQ(frames.size(), 2u);
    EXPECT_EQ(frames[0].raw, report_id);
    EXPECT_EQ(frames[1].raw, read_pv_request);
}

TEST(RtuDecoder, UnknownFunctionCompletedBySilence) {
    // FC17 (report server id) has no length loopwire knows: only silence ends it.
    const Bytes report_id = rtu_encode(0x05, hex("11"));
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(report_id, t0).empty());
    EXPECT_EQ(decoder.silence_deadline(), t0 + 4011us);
    EXPECT_TRUE(decoder.flush(t0 + 4010us).empty());
    const auto events = decoder.flush(t0 + 4011us);
    ASSERT_EQ(events.size(), 1u);
    const auto& frame = std::get<Frame>(events[0]);
    EXPECT_EQ(frame.unit, 5);
    EXPECT_EQ(frame.pdu, hex("11"));
    EXPECT_EQ(frame.raw, report_id);
    EXPECT_EQ(decoder.silence_deadline(), std::nullopt);
}

TEST(RtuDecoder, UnknownFunctionCompletedByTheNextFeedsGap) {
    const Bytes device_id = rtu_encode(0x01, hex("2B 0E 01 00"));  // FC43/14
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(device_id, t0).empty());
    const auto events = decoder.feed(read_pv_request, t0 + 50ms);
    const auto frames = frames_in(events);
    ASSERT_EQ(frames.size(), 2u);
    EXPECT_EQ(frames[0].raw, device_id);
    EXPECT_EQ(frames[1].raw, read_pv_request);
}

TEST(RtuDecoder, UnknownFunctionWithBadCrcIsDiscardedAtSilence) {
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(hex("05 11 00 00"), t0).empty());
    const auto events = decoder.flush(t0 + 1s);
    ASSERT_EQ(events.size(), 1u);
    const auto& discarded = std::get<DiscardedBytes>(events[0]);
    EXPECT_EQ(discarded.bytes, hex("05 11 00 00"));
    EXPECT_THAT(discarded.reason, HasSubstr("CRC mismatch"));
}

TEST(RtuDecoder, TooFewBytesBeforeSilence) {
    RtuDecoder decoder(Direction::reply, timing_9600());
    EXPECT_TRUE(decoder.feed(hex("01 83 03"), t0).empty());
    const auto events = decoder.flush(t0 + 1s);
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(std::get<DiscardedBytes>(events[0]).bytes, hex("01 83 03"));
    EXPECT_EQ(std::get<DiscardedBytes>(events[0]).reason, "gap inside frame: silence after 3 of 5 bytes");
    // Fewer than the 4 bytes of the smallest frame, and no function code to tell more.
    EXPECT_TRUE(decoder.feed(hex("01"), t0 + 2s).empty());
    const auto short_events = decoder.flush(t0 + 3s);
    ASSERT_EQ(short_events.size(), 1u);
    EXPECT_EQ(std::get<DiscardedBytes>(short_events[0]).reason,
              "1 byte before silence, too few for a frame (at least 4)");
}

TEST(RtuDecoder, SilenceDelimitsFramesOfTheOtherDirection) {
    // On a shared bus a slave also hears other slaves' replies. Read as a request, this FC3
    // reply (ramp/soak §4.7.1) would need 8 bytes; the silence after it says it has 7, and
    // its CRC checks, so it is handed on for the session to ignore.
    const Bytes reply = hex("01 03 02 03 E8 B8 FA");
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(reply, t0).empty());
    const auto frames = frames_in(decoder.flush(t0 + 5ms));
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].raw, reply);
}

TEST(RtuDecoder, LargestFramesAreAccepted) {
    const Bytes request = rtu_encode(
        1, encode_request(write_multiple_registers(0, std::vector<std::uint16_t>(123, 0x1234))).value());
    ASSERT_EQ(request.size(), 255u);
    RtuDecoder slave(Direction::request, timing_9600());
    EXPECT_EQ(frames_in(slave.feed(request, t0)).size(), 1u);

    Bytes reply_pdu{0x03, 250};
    reply_pdu.resize(252, 0x5A);
    const Bytes reply = rtu_encode(1, reply_pdu);
    RtuDecoder master(Direction::reply, timing_9600());
    EXPECT_EQ(frames_in(master.feed(reply, t0)).size(), 1u);
}

TEST(RtuDecoder, ImpliedLengthAbove256BytesIsDiscarded) {
    // FC16 with byte count FAh implies 1 + 6 + 250 + 2 = 259 bytes: no RTU frame is that long.
    const Bytes impossible = hex("01 10 00 00 00 7D FA");
    RtuDecoder decoder(Direction::request, timing_9600());
    FrameEvents events = decoder.feed(impossible, t0);
    append(events, decoder.flush(t0 + 1s));
    ASSERT_EQ(events.size(), 1u);
    const auto& discarded = std::get<DiscardedBytes>(events[0]);
    EXPECT_EQ(discarded.bytes, impossible);
    EXPECT_EQ(discarded.reason,
              "function 16 implies a 259-byte frame, more than the 256 an RTU frame can hold");
}

TEST(RtuDecoder, EndlessNoiseIsReportedInBoundedRuns) {
    // Every offset reads as "unit 10h, FC16, byte count 10h": a 25-byte candidate whose CRC
    // never matches. No gap and no frame: runs are cut at 256 bytes.
    const Bytes noise(600, 0x10);
    RtuDecoder decoder(Direction::request, timing_9600());
    FrameEvents events = decoder.feed(noise, t0);
    EXPECT_LE(decoder.buffered(), 256u);
    append(events, decoder.flush(t0 + 1s));
    std::size_t discarded = 0;
    for (const auto& run : discards_in(events)) {
        EXPECT_LE(run.bytes.size(), 256u);
        discarded += run.bytes.size();
    }
    EXPECT_EQ(discarded, noise.size());
    EXPECT_TRUE(frames_in(events).empty());
    EXPECT_EQ(decoder.buffered(), 0u);
}

TEST(RtuDecoder, SilenceDeadlineTracksTheLastArrival) {
    RtuDecoder decoder(Direction::request, CharacterTiming{38400, 11});
    EXPECT_EQ(decoder.silence_deadline(), std::nullopt);
    // Bytes that start no frame of known length: 3.5 characters end them.
    EXPECT_TRUE(decoder.feed(hex("05 11"), t0).empty());
    EXPECT_EQ(decoder.silence_deadline(), t0 + 1750us);
    EXPECT_TRUE(decoder.flush(t0 + 1ms).empty());  // 1 ms of silence is not enough
    EXPECT_EQ(decoder.buffered(), 2u);
    decoder.reset();
    // A frame under way (a read request is 8 bytes): the patience for a reader's batches.
    EXPECT_TRUE(decoder.feed(ByteView(read_pv_request).first(2), t0).empty());
    EXPECT_EQ(decoder.silence_deadline(), t0 + 20ms);
    EXPECT_TRUE(decoder.feed(ByteView(read_pv_request).subspan(2, 2), t0 + 1ms).empty());
    EXPECT_EQ(decoder.silence_deadline(), t0 + 1ms + 20ms);
    EXPECT_TRUE(decoder.flush(t0 + 2ms).empty());
    EXPECT_EQ(decoder.buffered(), 4u);
}

// A relay or USB adapter that hands a frame over in pieces with a few milliseconds between them
// (more than 3.5 characters at 19200 baud: 1.8 ms) makes no garbled frame: the reader's silence
// inside a frame under way is not the wire's.
TEST(RtuDecoder, AFrameHandedOverInPiecesWithJitterComesOutWhole) {
    const Bytes reply = hex("03 03 02 00 00 C1 84");
    RtuDecoder decoder(Direction::reply, CharacterTiming{19200, 10});
    FrameEvents events = decoder.feed(ByteView(reply).first(3), t0);
    append(events, decoder.flush(t0 + 3ms));  // the reader woke with nothing more
    append(events, decoder.feed(ByteView(reply).subspan(3, 2), t0 + 3ms));
    append(events, decoder.flush(t0 + 8ms));
    append(events, decoder.feed(ByteView(reply).subspan(5), t0 + 8ms));
    EXPECT_TRUE(discards_in(events).empty());
    const auto frames = frames_in(events);
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_EQ(frames[0].raw, reply);
}

TEST(RtuDecoder, EmptyFeedActsAsFlush) {
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(ByteView(read_pv_request).first(3), t0).empty());
    EXPECT_TRUE(decoder.feed({}, t0 + 1ms).empty());
    EXPECT_EQ(decoder.buffered(), 3u);
    EXPECT_EQ(discards_in(decoder.feed({}, t0 + 1s)).size(), 1u);
    EXPECT_EQ(decoder.buffered(), 0u);
}

TEST(RtuDecoder, FlushWithNothingPendingDoesNothing) {
    RtuDecoder decoder(Direction::reply, timing_9600());
    EXPECT_TRUE(decoder.flush(t0 + 1s).empty());
}

TEST(RtuDecoder, ResetForgetsPendingBytes) {
    RtuDecoder decoder(Direction::request, timing_9600());
    EXPECT_TRUE(decoder.feed(hex("07 03 01 03 00 8A 00 01"), t0).empty());  // one byte held as noise
    decoder.reset();
    EXPECT_EQ(decoder.buffered(), 0u);
    const auto events = decoder.feed(read_pv_request, t0 + 1ms);
    ASSERT_EQ(events.size(), 1u);  // no stale discard run
    EXPECT_EQ(std::get<Frame>(events[0]).raw, read_pv_request);
}

// Deterministic pseudo-random bytes (no <random> engine differences between libraries).
class NoiseSource {
public:
    explicit NoiseSource(std::uint32_t seed) : state_(seed) {}
    std::uint32_t next() {
        state_ = state_ * 1664525u + 1013904223u;
        return state_ >> 8;
    }

private:
    std::uint32_t state_;
};

// Every byte fed comes out exactly once, as part of a frame or a discarded run, and every
// frame is well-formed. Good frames mixed into the noise must mostly survive.
void expect_bytes_conserved(Direction direction, std::uint32_t seed) {
    NoiseSource noise(seed);
    RtuDecoder decoder(direction, timing_9600());
    FrameEvents events;
    Instant now = t0;
    std::size_t fed = 0;
    for (int chunk = 0; chunk < 2000; ++chunk) {
        Bytes bytes(noise.next() % 40);
        for (auto& byte : bytes) byte = static_cast<std::uint8_t>(noise.next());
        if (noise.next() % 4 == 0) {
            const Bytes good =
                direction == Direction::request ? read_pv_request : hex("01 03 02 03 E8 B8 FA");
            bytes.insert(bytes.end(), good.begin(), good.end());
        }
        fed += bytes.size();
        now += std::chrono::microseconds{noise.next() % 6000};
        append(events, decoder.feed(bytes, now));
    }
    append(events, decoder.flush(now + 1s));
    std::size_t accounted = 0;
    for (const auto& event : events) {
        if (const auto* frame = std::get_if<Frame>(&event)) {
            EXPECT_GE(frame->raw.size(), 4u);
            EXPECT_LE(frame->raw.size(), 256u);
            EXPECT_EQ(crc16(ByteView(frame->raw).first(frame->raw.size() - 2)), crc_as_sent(frame->raw));
            EXPECT_EQ(frame->pdu.size(), frame->raw.size() - 3);
            accounted += frame->raw.size();
        } else {
            const auto& discarded = std::get<DiscardedBytes>(event);
            EXPECT_FALSE(discarded.bytes.empty());
            EXPECT_FALSE(discarded.reason.empty());
            accounted += discarded.bytes.size();
        }
    }
    EXPECT_EQ(accounted, fed);
    EXPECT_EQ(decoder.buffered(), 0u);
    EXPECT_GT(frames_in(events).size(), 100u);  // about 500 good frames went in
}

TEST(RtuDecoder, HostileInputConservesBytesAsSlave) { expect_bytes_conserved(Direction::request, 1); }
TEST(RtuDecoder, HostileInputConservesBytesAsMaster) { expect_bytes_conserved(Direction::reply, 2); }

// ---- example frames from the manuals --------------------------------------------------------
//
// Each test takes the frame as the manual prints it (wire order), checks the CRC, runs it
// through an RtuDecoder of the right direction, decodes the PDU and checks the fields against
// what the manual says the frame means.

// The printed frame's CRC checks and a decoder delivers it whole. Returns an empty Frame on
// failure (the test has already failed then, and decoding the empty PDU fails too).
Frame expect_manual_frame(std::string_view printed, Direction direction) {
    const Bytes wire = hex(printed);
    if (wire.size() < 4) {
        ADD_FAILURE() << "frame too short: " << printed;
        return Frame{};
    }
    EXPECT_EQ(crc_of_body(wire), crc_as_sent(wire)) << printed;
    RtuDecoder decoder(direction, CharacterTiming{});
    const auto events = decoder.feed(wire, t0);
    const auto frames = frames_in(events);
    if (events.size() != 1 || frames.size() != 1) {
        ADD_FAILURE() << "decoder did not deliver exactly one frame for " << printed;
        return Frame{};
    }
    EXPECT_EQ(frames[0].raw, wire);
    EXPECT_EQ(frames[0].pdu, Bytes(wire.begin() + 1, wire.end() - 2));
    return frames[0];
}

Request expect_manual_request(std::string_view printed, std::uint8_t unit) {
    const Frame frame = expect_manual_frame(printed, Direction::request);
    EXPECT_EQ(frame.unit, unit);
    auto request = decode_request(frame.pdu);
    EXPECT_TRUE(request.ok()) << printed << ": " << (request.ok() ? "" : request.error().message);
    return request.ok() ? request.value() : Request{};
}

Reply expect_manual_reply(std::string_view printed, std::uint8_t unit) {
    const Frame frame = expect_manual_frame(printed, Direction::reply);
    EXPECT_EQ(frame.unit, unit);
    auto reply = decode_reply(frame.pdu);
    EXPECT_TRUE(reply.ok()) << printed << ": " << (reply.ok() ? "" : reply.error().message);
    return reply.ok() ? reply.value() : Reply{};
}

// -- AC20, English (ac20-modbus-jbus-eng824e.en.txt) and Korean (.ko.txt) editions. The twelve
//    example frames are byte-identical in both (AUDIT.md §2); each edition gets its own test so
//    a report names the document.

// "Function code 1 and 2: Bits reading" / Example: slave 100, bits 201..214.
void expect_ac20_fc01_request(std::string_view printed) {
    const Request request = expect_manual_request(printed, 100);
    EXPECT_EQ(request, read_request(FunctionCode::read_coils, 201, 14));
}

// Same example, reply: byte count 2, A7h 04h; the two padding bits are 0.
void expect_ac20_fc01_reply(std::string_view printed) {
    const Reply reply = expect_manual_reply(printed, 100);
    EXPECT_EQ(reply.function, 1);
    EXPECT_EQ(reply.values.size(), 16u);  // byte count 2 -> 16 bits before trimming
    const auto matched = match_reply(read_request(FunctionCode::read_coils, 201, 14), reply);
    ASSERT_TRUE(matched.ok()) << matched.error().message;
    EXPECT_EQ(matched->address, 201);
    EXPECT_THAT(matched->values, ElementsAre(1, 1, 1, 0, 0, 1, 0, 1, 0, 0, 1, 0, 0, 0));
    EXPECT_EQ(reply.values[14], 0);
    EXPECT_EQ(reply.values[15], 0);
}

// "Function code 3 and 4: Words reading" / Example: slave 29, words 178..180.
void expect_ac20_fc03_request(std::string_view printed) {
    EXPECT_EQ(expect_manual_request(printed, 29), read_request(FunctionCode::read_holding_registers, 178, 3));
}

// Reply: FF9Ch = -100, 8000h = not implemented / not relevant, 055Ah = 1370.
void expect_ac20_fc03_reply(std::string_view printed) {
    const Reply reply = expect_manual_reply(printed, 29);
    const auto matched = match_reply(read_request(FunctionCode::read_holding_registers, 178, 3), reply);
    ASSERT_TRUE(matched.ok()) << matched.error().message;
    EXPECT_THAT(matched->values, ElementsAre(0xFF9C, 0x8000, 0x055A));
    EXPECT_EQ(static_cast<std::int16_t>(matched->values[0]), -100);
    EXPECT_EQ(matched->values[2], 1370);
}

// "Function code 5: Single bit writing" / Example: slave 35, bit 219 = FF00h (set). The reply
// is the echo of the request, byte for byte.
void expect_ac20_fc05_exchange(std::string_view request_printed, std::string_view reply_printed) {
    const Request request = expect_manual_request(request_printed, 35);
    EXPECT_EQ(request, write_single_coil(219, true));
    const Reply reply = expect_manual_reply(reply_printed, 35);
    EXPECT_EQ(reply.address, 219);
    EXPECT_THAT(reply.values, ElementsAre(1));
    EXPECT_TRUE(match_reply(request, reply).ok());
}

// "Function code 6: Single word writing" / Example: slave 5, word 2006 = 1250; echo reply.
void expect_ac20_fc06_exchange(std::string_view request_printed, std::string_view reply_printed) {
    const Request request = expect_manual_request(request_printed, 5);
    EXPECT_EQ(request, write_single_register(2006, 1250));
    const Reply reply = expect_manual_reply(reply_printed, 5);
    EXPECT_EQ(reply.address, 2006);
    EXPECT_THAT(reply.values, ElementsAre(1250));
    EXPECT_TRUE(match_reply(request, reply).ok());
}

// "Function code 15: Multiple bits writing" / Example: slave 2, bits 224..232 =
// 0,1,1,0,1,0,1,1,1 packed as D6h 01h (7 padding bits 0).
void expect_ac20_fc15_request(std::string_view printed) {
    const Request request = expect_manual_request(printed, 2);
    EXPECT_EQ(request.function, 15);
    EXPECT_EQ(request.address, 224);
    EXPECT_EQ(request.count, 9);
    EXPECT_THAT(request.values, ElementsAre(0, 1, 1, 0, 1, 0, 1, 1, 1));
    EXPECT_EQ(pack_bits(request.values), hex("D6 01"));
}

void expect_ac20_fc15_reply(std::string_view printed) {
    const Reply reply = expect_manual_reply(printed, 2);
    EXPECT_EQ(reply.function, 15);
    EXPECT_EQ(reply.address, 224);
    EXPECT_EQ(reply.count, 9);
    EXPECT_TRUE(match_reply(write_multiple_coils(224, {0, 1, 1, 0, 1, 0, 1, 1, 1}), reply).ok());
}

// "Function code 16: Multiple words writing" / Example: slave 10, words 139..141 = 300,
// 8000h (don't care: the device leaves that word unchanged), 700.
void expect_ac20_fc16_request(std::string_view printed) {
    const Request request = expect_manual_request(printed, 10);
    EXPECT_EQ(request, write_multiple_registers(139, {300, 0x8000, 700}));
}

void expect_ac20_fc16_reply(std::string_view printed) {
    const Reply reply = expect_manual_reply(printed, 10);
    EXPECT_EQ(reply.address, 139);
    EXPECT_EQ(reply.count, 3);
    EXPECT_TRUE(match_reply(write_multiple_registers(139, {300, 0x8000, 700}), reply).ok());
}

TEST(RtuManualFrames, Ac20En_Fc01Example_ReadBits201To214_Request) {
    expect_ac20_fc01_request("64 01 00 C9 00 0E 64 05");
}
TEST(RtuManualFrames, Ac20En_Fc01Example_ReadBits201To214_Reply) {
    expect_ac20_fc01_reply("64 01 02 A7 04 8E 07");
}
TEST(RtuManualFrames, Ac20En_Fc03Example_ReadWords178To180_Request) {
    expect_ac20_fc03_request("1D 03 00 B2 00 03 A7 B0");
}
TEST(RtuManualFrames, Ac20En_Fc03Example_ReadWords178To180_Reply) {
    expect_ac20_fc03_reply("1D 03 06 FF 9C 80 00 05 5A D7 0D");
}
TEST(RtuManualFrames, Ac20En_Fc05Example_SetBit219) {
    expect_ac20_fc05_exchange("23 05 00 DB FF 00 FA 83", "23 05 00 DB FF 00 FA 83");
}
TEST(RtuManualFrames, Ac20En_Fc06Example_WriteWord2006) {
    expect_ac20_fc06_exchange("05 06 07 D6 04 E2 EA 4B", "05 06 07 D6 04 E2 EA 4B");
}
TEST(RtuManualFrames, Ac20En_Fc15Example_WriteBits224To232_Request) {
    expect_ac20_fc15_request("02 0F 00 E0 00 09 02 D6 01 78 4C");
}
TEST(RtuManualFrames, Ac20En_Fc15Example_WriteBits224To232_Reply) {
    expect_ac20_fc15_reply("02 0F 00 E0 00 09 94 08");
}
TEST(RtuManualFrames, Ac20En_Fc16Example_WriteWords139To141_Request) {
    expect_ac20_fc16_request("0A 10 00 8B 00 03 06 01 2C 80 00 02 BC 33 00");
}
TEST(RtuManualFrames, Ac20En_Fc16Example_WriteWords139To141_Reply) {
    expect_ac20_fc16_reply("0A 10 00 8B 00 03 F1 59");
}

// Korean edition (ac20-modbus-jbus-eng824e.ko.txt), sections "… / Example":
//   FC1: "기능 코드 1 과 2 : Bits 읽기"      FC3: "기능 코드 3과 4 : 단어 읽기"
//   FC5: "기능 코드 5 : 단일 비트 쓰기"      FC6: "기능 코드 6 : 단일 단어 쓰기"
//   FC15: "기능 코드 15 : 다중 비트 쓰기"    FC16: "기능 코드 16 : 다중 단어 쓰기"
TEST(RtuManualFrames, Ac20Ko_Fc01Example_ReadBits201To214_Request) {
    expect_ac20_fc01_request("64 01 00 C9 00 0E 64 05");
}
TEST(RtuManualFrames, Ac20Ko_Fc01Example_ReadBits201To214_Reply) {
    expect_ac20_fc01_reply("64 01 02 A7 04 8E 07");
}
TEST(RtuManualFrames, Ac20Ko_Fc03Example_ReadWords178To180_Request) {
    expect_ac20_fc03_request("1D 03 00 B2 00 03 A7 B0");
}
TEST(RtuManualFrames, Ac20Ko_Fc03Example_ReadWords178To180_Reply) {
    expect_ac20_fc03_reply("1D 03 06 FF 9C 80 00 05 5A D7 0D");
}
TEST(RtuManualFrames, Ac20Ko_Fc05Example_SetBit219) {
    expect_ac20_fc05_exchange("23 05 00 DB FF 00 FA 83", "23 05 00 DB FF 00 FA 83");
}
TEST(RtuManualFrames, Ac20Ko_Fc06Example_WriteWord2006) {
    expect_ac20_fc06_exchange("05 06 07 D6 04 E2 EA 4B", "05 06 07 D6 04 E2 EA 4B");
}
TEST(RtuManualFrames, Ac20Ko_Fc15Example_WriteBits224To232_Request) {
    expect_ac20_fc15_request("02 0F 00 E0 00 09 02 D6 01 78 4C");
}
TEST(RtuManualFrames, Ac20Ko_Fc15Example_WriteBits224To232_Reply) {
    expect_ac20_fc15_reply("02 0F 00 E0 00 09 94 08");
}
TEST(RtuManualFrames, Ac20Ko_Fc16Example_WriteWords139To141_Request) {
    expect_ac20_fc16_request("0A 10 00 8B 00 03 06 01 2C 80 00 02 BC 33 00");
}
TEST(RtuManualFrames, Ac20Ko_Fc16Example_WriteWords139To141_Reply) {
    expect_ac20_fc16_reply("0A 10 00 8B 00 03 F1 59");
}

// -- Ramp/soak PID controller (rampsoak-pid-rtu-ascii-linking.en.txt), §4.7 "Message example of
//    RTU mode". The manual prints the CRC as one hex number, e.g. (A5E0H); §4.5 step ⑨ swaps the
//    register's bytes first, so the printed number reads in wire order.

TEST(RtuManualFrames, RampSoak_4_7_1_ReadPv_Request) {
    // Read PV (register 008Ah = 138) from slave 1.
    EXPECT_EQ(expect_manual_request("01 03 00 8A 00 01 A5 E0", 1),
              read_request(FunctionCode::read_holding_registers, 138, 1));
}

TEST(RtuManualFrames, RampSoak_4_7_1_ReadPv_Reply) {
    // PV = 03E8h = 1000, displayed as 100.0.
    const Reply reply = expect_manual_reply("01 03 02 03 E8 B8 FA", 1);
    const auto matched = match_reply(read_request(FunctionCode::read_holding_registers, 138, 1), reply);
    ASSERT_TRUE(matched.ok()) << matched.error().message;
    EXPECT_THAT(matched->values, ElementsAre(1000));
}

TEST(RtuManualFrames, RampSoak_4_7_1_ReadPv_ExceptionIllegalDataValue) {
    const Reply reply = expect_manual_reply("01 83 03 01 31", 1);
    EXPECT_EQ(reply, exception_reply(3, 3));
}

TEST(RtuManualFrames, RampSoak_4_7_2_SetSv_Request) {
    // SV (register 0) = 0064h = 100, displayed as 10.0.
    EXPECT_EQ(expect_manual_request("01 06 00 00 00 64 88 21", 1), write_single_register(0, 100));
}

TEST(RtuManualFrames, RampSoak_4_7_2_SetSv_Reply) {
    const Reply reply = expect_manual_reply("01 06 00 00 00 64 88 21", 1);
    EXPECT_EQ(reply.address, 0);
    EXPECT_THAT(reply.values, ElementsAre(100));
    EXPECT_TRUE(match_reply(write_single_register(0, 100), reply).ok());
}

TEST(RtuManualFrames, RampSoak_4_7_2_SetSv_ExceptionIllegalDataValue) {
    EXPECT_EQ(expect_manual_reply("01 86 03 02 61", 1), exception_reply(6, 3));
}

TEST(RtuManualFrames, RampSoak_4_7_3_SetSvAndOutl_Request) {
    // SV = 0064h (10.0), OUTL = 03E8h (100.0), byte count 4.
    EXPECT_EQ(expect_manual_request("01 10 00 00 00 02 04 00 64 03 E8 B2 CE", 1),
              write_multiple_registers(0, {100, 1000}));
}

TEST(RtuManualFrames, RampSoak_4_7_3_SetSvAndOutl_Reply) {
    const Reply reply = expect_manual_reply("01 10 00 00 00 02 41 C8", 1);
    EXPECT_EQ(reply.address, 0);
    EXPECT_EQ(reply.count, 2);
    EXPECT_TRUE(match_reply(write_multiple_registers(0, {100, 1000}), reply).ok());
}

// MANUAL ERROR: §4.7.3 prints the FC16 exception reply as 01 90 02 with CRC (C001H). The CRC
// of 01 90 02 is CDC1h in wire order (CD C1); C0 01 is the CRC of 01 80 02 — computed with
// function byte 80h instead of 90h. Swapping the bytes does not help either. The ASCII version
// of the same frame in §5.7.2 (LRC 6Dh) is right for 90h. See AUDIT.md §1 (pid-rtu-fc16-exc).
TEST(RtuManualFrames, RampSoak_4_7_3_ExceptionAsPrinted_HasWrongCrcAndIsRejected) {
    const Bytes printed = hex("01 90 02 C0 01");
    EXPECT_EQ(crc16(hex("01 90 02")), 0xC1CD);  // wire order CD C1
    EXPECT_EQ(crc16(hex("01 80 02")), 0x01C0);  // wire order C0 01: the printed bytes
    RtuDecoder decoder(Direction::reply, CharacterTiming{38400, 11});
    FrameEvents events = decoder.feed(printed, t0);
    append(events, decoder.flush(t0 + 1s));
    EXPECT_TRUE(frames_in(events).empty());
    const auto discards = discards_in(events);
    ASSERT_EQ(discards.size(), 1u);
    EXPECT_EQ(discards[0].bytes, printed);
    EXPECT_EQ(discards[0].reason, "CRC mismatch: computed CD C1, received C0 01");
}

TEST(RtuManualFrames, RampSoak_4_7_3_ExceptionCorrected_IllegalRegisterAddress) {
    EXPECT_EQ(expect_manual_reply("01 90 02 CD C1", 1), exception_reply(16, 2));
    EXPECT_EQ(rtu_encode(1, encode_reply(exception_reply(16, 2)).value()), hex("01 90 02 CD C1"));
}

// -- Yokogawa TC10 (tc10-modbus-im05c01e81-03.ru.txt), §3 "Функциональный код …" / "Пример".
//    §3.5: the CRC's low byte goes first; the tables label the two CRC rows LSB then MSB.

TEST(RtuManualFrames, Tc10_3_1_Fc03Example_ReadRegisters25And26_Request) {
    EXPECT_EQ(expect_manual_request("01 03 00 19 00 02 15 CC", 1),
              read_request(FunctionCode::read_holding_registers, 25, 2));
}

TEST(RtuManualFrames, Tc10_3_1_Fc03Example_ReadRegisters25And26_Reply) {
    const Reply reply = expect_manual_reply("01 03 04 00 0A 00 14 DA 3E", 1);
    const auto matched = match_reply(read_request(FunctionCode::read_holding_registers, 25, 2), reply);
    ASSERT_TRUE(matched.ok()) << matched.error().message;
    EXPECT_THAT(matched->values, ElementsAre(10, 20));
}

// MANUAL ERROR (labels only): §3.2 labels the CRC rows "CRC-16 (MSB) A8" then "CRC-16 (LSB) 49".
// The CRC register is 49A8h, so A8 is the LSB. The bytes and their order are right (low byte
// first, as §3.5 and §3.1/§3.3 have it); only the MSB/LSB labels are swapped. This holds for
// the format table, the request and the reply example alike (AUDIT.md §1, tc10-fc06-*).
TEST(RtuManualFrames, Tc10_3_2_Fc06FormatTable_WriteRegister770) {
    EXPECT_EQ(crc16(hex("01 06 03 02 00 0A")), 0x49A8);
    EXPECT_EQ(expect_manual_request("01 06 03 02 00 0A A8 49", 1), write_single_register(770, 10));
}

TEST(RtuManualFrames, Tc10_3_2_Fc06Example_WriteRegister770_Request) {
    EXPECT_EQ(expect_manual_request("01 06 03 02 00 0A A8 49", 1), write_single_register(770, 10));
}

TEST(RtuManualFrames, Tc10_3_2_Fc06Example_WriteRegister770_Reply) {
    const Reply reply = expect_manual_reply("01 06 03 02 00 0A A8 49", 1);
    EXPECT_EQ(reply.address, 770);
    EXPECT_THAT(reply.values, ElementsAre(10));
    EXPECT_TRUE(match_reply(write_single_register(770, 10), reply).ok());
}

TEST(RtuManualFrames, Tc10_3_3_Fc16Example_WriteRegisters10314And10315_Request) {
    // 10314 (284Ah) = 100, 10315 = 200.
    EXPECT_EQ(expect_manual_request("01 10 28 4A 00 02 04 00 64 00 C8 C9 A8", 1),
              write_multiple_registers(10314, {100, 200}));
}

TEST(RtuManualFrames, Tc10_3_3_Fc16Example_WriteRegisters10314And10315_Reply) {
    const Reply reply = expect_manual_reply("01 10 28 4A 00 02 69 BE", 1);
    EXPECT_EQ(reply.address, 10314);
    EXPECT_EQ(reply.count, 2);
    EXPECT_TRUE(match_reply(write_multiple_registers(10314, {100, 200}), reply).ok());
}

// The frame list as data: every "protocol": "rtu" entry decodes, except the one the audit marks
// check_ok = false, which must be the ramp/soak FC16 exception and must fail its CRC. Guards
// against the named tests above drifting from the list.
TEST(RtuManualFrames, EveryRtuEntryInTheFrameList) {
    std::ifstream file(std::string(LOOPWIRE_TEST_DATA_DIR) + "/manual-example-frames.json");
    ASSERT_TRUE(file) << "cannot open manual-example-frames.json";
    const auto frames = nlohmann::json::parse(file);
    std::size_t rtu_frames = 0;
    for (const auto& entry : frames) {
        if (entry.at("protocol") != "rtu") continue;
        ++rtu_frames;
        const std::string id = entry.at("id");
        const Bytes wire = hex(entry.at("hex").get<std::string>());
        ASSERT_GE(wire.size(), 4u) << id;
        const bool crc_ok = crc_of_body(wire) == crc_as_sent(wire);
        EXPECT_EQ(crc_ok, entry.at("check_ok").get<bool>()) << id;
        if (!crc_ok) {
            EXPECT_EQ(id, "pid-rtu-fc16-exc");
            continue;
        }
        const bool is_request = entry.at("direction") == "request";
        const Frame frame = expect_manual_frame(entry.at("hex").get<std::string>(),
                                                is_request ? Direction::request : Direction::reply);
        if (is_request) {
            EXPECT_TRUE(decode_request(frame.pdu).ok()) << id;
        } else {
            const auto reply = decode_reply(frame.pdu);
            ASSERT_TRUE(reply.ok()) << id;
            EXPECT_EQ(reply->kind == ReplyKind::exception, entry.at("direction") == "exception") << id;
        }
    }
    EXPECT_EQ(rtu_frames, 40u);  // 24 AC20 (en + ko), 9 ramp/soak, 7 TC10
}

}  // namespace
}  // namespace loopwire::codec
