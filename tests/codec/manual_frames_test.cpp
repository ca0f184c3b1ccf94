// Every example frame of the four manuals (AUDIT.md §1, listed in manual-example-frames.json),
// decoded with the decoder of its protocol. A frame must decode exactly when the audit found
// its printed check bytes right ("check_ok"); the one it found wrong (ramp/soak §4.7.3 RTU
// FC16 exception, CRC printed C0 01 instead of CD C1) must be refused.
#include <gtest/gtest.h>

#include <chrono>
#include <cctype>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "codec/ascii.hpp"
#include "codec/linking.hpp"
#include "codec/pdu.hpp"
#include "codec/rtu.hpp"

namespace loopwire::codec {
namespace {

struct ManualFrame {
    std::string id;
    std::string section;
    std::string protocol;   // "rtu", "ascii" or "linking"
    std::string direction;  // "request", "reply" or "exception"
    std::string wire;       // hex bytes (rtu, linking) or the ASCII characters themselves
    bool check_ok = false;
};

// gtest prints parameters it cannot name as raw bytes; this keeps failure messages readable.
void PrintTo(const ManualFrame& frame, std::ostream* os) { *os << frame.id << " (" << frame.section << ")"; }

const std::string frames_file = LOOPWIRE_TEST_DATA_DIR "/manual-example-frames.json";

std::vector<ManualFrame> load_frames() {
    std::ifstream in(frames_file);
    if (!in) return {};  // ManualFrameFile.Has54Frames reports it
    const nlohmann::json json = nlohmann::json::parse(in);
    std::vector<ManualFrame> frames;
    for (const auto& entry : json) {
        frames.push_back(ManualFrame{entry.at("id").get<std::string>(), entry.at("section").get<std::string>(),
                                     entry.at("protocol").get<std::string>(),
                                     entry.at("direction").get<std::string>(),
                                     entry.at("hex").get<std::string>(), entry.at("check_ok").get<bool>()});
    }
    return frames;
}

const std::vector<ManualFrame>& all_frames() {
    static const std::vector<ManualFrame> frames = load_frames();
    return frames;
}

Bytes wire_bytes(const ManualFrame& frame) {
    if (frame.protocol == "ascii") return Bytes(frame.wire.begin(), frame.wire.end());
    auto bytes = parse_hex(frame.wire);
    EXPECT_TRUE(bytes.has_value()) << frame.id << ": bad hex " << frame.wire;
    return bytes.value_or(Bytes{});
}

bool is_request(const ManualFrame& frame) { return frame.direction == "request"; }

// Frames the decoder handed out; any discard is printed so a failure shows the reason.
std::vector<Frame> frames_of(const FrameEvents& events) {
    std::vector<Frame> frames;
    for (const FrameEvent& event : events) {
        if (const auto* frame = std::get_if<Frame>(&event)) frames.push_back(*frame);
        else std::cout << "  discarded " << to_hex(std::get<DiscardedBytes>(event).bytes) << ": "
                       << std::get<DiscardedBytes>(event).reason << '\n';
    }
    return frames;
}

// The PDU must decode in the frame's direction, and exceptions must come out as exceptions.
bool pdu_decodes(const ManualFrame& manual, const Frame& frame) {
    if (is_request(manual)) {
        const auto request = decode_request(frame.pdu);
        EXPECT_TRUE(request.ok()) << (request.ok() ? "" : request.error().message);
        return request.ok();
    }
    const auto reply = decode_reply(frame.pdu);
    EXPECT_TRUE(reply.ok()) << (reply.ok() ? "" : reply.error().message);
    if (!reply.ok()) return false;
    const ReplyKind expected = manual.direction == "exception" ? ReplyKind::exception : ReplyKind::normal;
    EXPECT_EQ(reply->kind, expected);
    return reply->kind == expected;
}

// Whole frame as framed by the decoder: one Frame carrying the unit and the bytes between.
bool framed_exactly(const std::vector<Frame>& frames, std::uint8_t unit, ByteView pdu) {
    if (frames.size() != 1) return false;
    EXPECT_EQ(frames[0].unit, unit);
    EXPECT_EQ(frames[0].pdu, Bytes(pdu.begin(), pdu.end()));
    return frames[0].unit == unit && frames[0].pdu == Bytes(pdu.begin(), pdu.end());
}

bool decodes_as_rtu(const ManualFrame& manual, const Bytes& wire) {
    // The manuals' own baud rates do not matter: the decoder delimits by length, and a flush
    // long after the last byte stands for the silence that ends the frame on a real line.
    const Direction direction = is_request(manual) ? Direction::request : Direction::reply;
    RtuDecoder decoder(direction, CharacterTiming{19200, 11});
    const Instant start{};
    FrameEvents events = decoder.feed(wire, start);
    FrameEvents after_silence = decoder.flush(start + std::chrono::seconds(1));
    events.insert(events.end(), after_silence.begin(), after_silence.end());

    // The CRC on its own agrees with the decoder (low byte first on the wire).
    const bool crc_ok = wire.size() >= 4 &&
                        crc16(ByteView(wire).first(wire.size() - 2)) ==
                            (wire[wire.size() - 2] | (wire[wire.size() - 1] << 8));
    const std::vector<Frame> frames = frames_of(events);
    EXPECT_EQ(!frames.empty(), crc_ok);
    if (!framed_exactly(frames, wire[0], ByteView(wire).subspan(1, wire.size() - 3))) return false;
    EXPECT_EQ(frames[0].raw, wire);
    return pdu_decodes(manual, frames[0]);
}

bool decodes_as_ascii(const ManualFrame& manual, const Bytes& wire) {
    AsciiDecoder decoder;
    const std::vector<Frame> frames = frames_of(decoder.feed(wire));
    if (frames.size() != 1) return false;
    EXPECT_EQ(frames[0].raw, wire);
    // Re-encoding gives back the manual's characters (upper-case hex, §5.7).
    EXPECT_EQ(ascii_encode(frames[0].unit, frames[0].pdu), wire);
    return pdu_decodes(manual, frames[0]);
}

bool decodes_as_linking(const ManualFrame& manual, const Bytes& wire) {
    const bool replies = !is_request(manual);
    LinkingDecoder decoder(replies);
    std::size_t streamed = 0;
    for (const LinkingEvent& event : decoder.feed(wire)) {
        if (event.frame) {
            EXPECT_EQ(*event.frame, wire);
            ++streamed;
        }
    }
    if (replies) {
        const auto reply = decode_linking_reply(wire);
        EXPECT_EQ(reply.ok(), streamed == 1) << (reply.ok() ? "" : reply.error().message);
        if (reply.ok()) {
        EXPECT_EQ(encode_linking_reply(*reply), wire);
    }
        return reply.ok() && streamed == 1;
    }
    const auto request = decode_linking_request(wire);
    EXPECT_EQ(request.ok(), streamed == 1) << (request.ok() ? "" : request.error().message);
    if (request.ok()) {
        EXPECT_EQ(encode_linking_request(*request), wire);
    }
    return request.ok() && streamed == 1;
}

class ManualFrameTest : public ::testing::TestWithParam<ManualFrame> {};

TEST_P(ManualFrameTest, DecodesExactlyWhenItsCheckIsRight) {
    const ManualFrame& manual = GetParam();
    const Bytes wire = wire_bytes(manual);
    ASSERT_FALSE(wire.empty());
    bool decoded = false;
    if (manual.protocol == "rtu") decoded = decodes_as_rtu(manual, wire);
    else if (manual.protocol == "ascii") decoded = decodes_as_ascii(manual, wire);
    else if (manual.protocol == "linking") decoded = decodes_as_linking(manual, wire);
    else FAIL() << "unknown protocol " << manual.protocol;
    EXPECT_EQ(decoded, manual.check_ok) << manual.id << " (" << manual.section << ")";
}

std::string test_name(const ::testing::TestParamInfo<ManualFrame>& info) {
    std::string name = info.param.id;
    for (char& c : name) {
        if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
    }
    return name;
}

INSTANTIATE_TEST_SUITE_P(Manuals, ManualFrameTest, ::testing::ValuesIn(all_frames()), test_name);

TEST(ManualFrameFile, Has54Frames) {
    ASSERT_EQ(all_frames().size(), 54u) << "could not read " << frames_file << " or it changed";
    std::size_t rtu = 0, ascii = 0, linking = 0, bad = 0;
    for (const ManualFrame& frame : all_frames()) {
        rtu += frame.protocol == "rtu";
        ascii += frame.protocol == "ascii";
        linking += frame.protocol == "linking";
        bad += !frame.check_ok;
    }
    EXPECT_EQ(rtu, 40u);
    EXPECT_EQ(ascii, 9u);
    EXPECT_EQ(linking, 5u);
    EXPECT_EQ(bad, 1u);
}

// AUDIT.md: the printed CRC C0 01 is the CRC of 01 80 02, and the corrected frame decodes.
TEST(ManualFrameFile, RampSoak_4_7_3_Fc16ExceptionCorrectedCrcIsCDC1) {
    EXPECT_EQ(crc16(Bytes{0x01, 0x80, 0x02}), 0x01C0);
    EXPECT_EQ(rtu_encode(0x01, Bytes{0x90, 0x02}), (Bytes{0x01, 0x90, 0x02, 0xCD, 0xC1}));
    RtuDecoder decoder(Direction::reply, CharacterTiming{});
    const FrameEvents events = decoder.feed(Bytes{0x01, 0x90, 0x02, 0xCD, 0xC1}, Instant{});
    ASSERT_EQ(events.size(), 1u);
    ASSERT_TRUE(std::holds_alternative<Frame>(events[0]));
    EXPECT_EQ(std::get<Frame>(events[0]).pdu, (Bytes{0x90, 0x02}));
}

}  // namespace
}  // namespace loopwire::codec
