#pragma once
// Replays a manual's example request (tests/codec/data/manual-example-frames.json) against a
// behaviour model: the frame is decoded with the codec of its protocol, its PDU goes to the
// simulator, and the simulator's reply PDU is framed again with the same framing and unit, so
// the result compares byte for byte with the manual's printed reply.
#include <fstream>
#include <map>
#include <memory>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "codec/ascii.hpp"
#include "codec/rtu.hpp"
#include "common/bytes.hpp"
#include "simulation/simulator_harness.hpp"
#include "session/linking_frame_codec.hpp"

namespace loopwire::device::testing {

struct ExampleFrame {
    std::string protocol;  // "rtu", "ascii" or "linking"
    std::string text;      // hex bytes (rtu, linking) or the ASCII characters themselves
    std::string section;
};

inline const std::map<std::string, ExampleFrame>& example_frames() {
    static const std::map<std::string, ExampleFrame> frames = [] {
        std::map<std::string, ExampleFrame> loaded;
        std::ifstream in(LOOPWIRE_MANUAL_FRAMES);
        if (!in) return loaded;
        for (const auto& entry : nlohmann::json::parse(in)) {
            loaded[entry.at("id").get<std::string>()] = {entry.at("protocol").get<std::string>(),
                                                         entry.at("hex").get<std::string>(),
                                                         entry.at("section").get<std::string>()};
        }
        return loaded;
    }();
    return frames;
}

inline const ExampleFrame& example(const std::string& id) {
    static const ExampleFrame missing{};
    const auto it = example_frames().find(id);
    EXPECT_NE(it, example_frames().end()) << id << " is not in " << LOOPWIRE_MANUAL_FRAMES;
    return it == example_frames().end() ? missing : it->second;
}

// The frame's wire bytes: ASCII frames are their characters, the others are printed as hex.
inline Bytes wire_of(const ExampleFrame& frame) {
    if (frame.protocol == "ascii") return Bytes(frame.text.begin(), frame.text.end());
    return parse_hex(frame.text).value_or(Bytes{});
}

// How the reply to a replayed request is written, for comparison with the manual: hex for
// RTU and Linking, the characters for ASCII; "silence" when the device does not answer.
inline std::string shown(const std::string& protocol, const Bytes& wire) {
    if (protocol == "ascii") return std::string(wire.begin(), wire.end());
    return to_hex(wire);
}

// Sends the example request `request_id` to `device` and returns its framed reply.
inline std::string replay(Simulated& device, const std::string& request_id) {
    const ExampleFrame& request = example(request_id);
    const Bytes wire = wire_of(request);
    codec::FrameEvents events;
    std::unique_ptr<session::FrameCodec> linking;
    if (request.protocol == "rtu") {
        codec::RtuDecoder decoder(codec::Direction::request, codec::CharacterTiming{19200, 11});
        events = decoder.feed(wire, Instant{});
        for (auto& event : decoder.flush(Instant{} + std::chrono::seconds(1))) events.push_back(event);
    } else if (request.protocol == "ascii") {
        codec::AsciiDecoder decoder;
        events = decoder.feed(wire);
    } else {
        linking = session::make_linking_frame_codec(codec::Direction::request, false);
        auto fed = linking->feed(wire, Instant{});
        if (fed.ok()) events = *fed;
    }
    EXPECT_EQ(events.size(), 1u) << request_id;
    const auto* frame = events.empty() ? nullptr : std::get_if<codec::Frame>(&events[0]);
    if (frame == nullptr) return "undecodable request " + request_id;
    const std::string reply_pdu = device.send_pdu(frame->pdu);
    if (reply_pdu == "silence") return reply_pdu;
    const Bytes pdu = parse_hex(reply_pdu).value_or(Bytes{});
    if (request.protocol == "rtu") return shown("rtu", codec::rtu_encode(frame->unit, pdu));
    if (request.protocol == "ascii") return shown("ascii", codec::ascii_encode(frame->unit, pdu));
    auto framed = linking->encode(frame->unit, pdu, 0);
    return framed.ok() ? shown("linking", *framed) : "unframable reply " + reply_pdu;
}

// The reply to a PDU the test builds itself (a request that causes an exception example),
// framed for `protocol` ("rtu" or "ascii") and `unit`.
inline std::string answer(Simulated& device, const std::string& protocol, std::uint8_t unit, const Bytes& pdu) {
    const std::string reply_pdu = device.send_pdu(pdu);
    if (reply_pdu == "silence") return reply_pdu;
    const Bytes reply = parse_hex(reply_pdu).value_or(Bytes{});
    return protocol == "ascii" ? shown("ascii", codec::ascii_encode(unit, reply))
                               : shown("rtu", codec::rtu_encode(unit, reply));
}

// The manual's printed frame `id`, written as replay() writes replies.
inline std::string printed(const std::string& id) {
    const ExampleFrame& frame = example(id);
    return shown(frame.protocol, wire_of(frame));
}

}  // namespace loopwire::device::testing
