#include "app/frame_explanation.hpp"

#include <fmt/format.h>

#include "codec/ascii.hpp"
#include "codec/linking.hpp"
#include "codec/pdu.hpp"
#include "codec/rtu.hpp"
#include "codec/tcp.hpp"

namespace loopwire::app {
namespace {

void fill_from_request(const codec::Request& request, FrameExplanation& out) {
    out.kind = "request";
    out.function = request.function;
    out.address = request.address;
    out.count = request.count;
    out.values = request.values;
}

void fill_from_reply(const codec::Reply& reply, FrameExplanation& out) {
    out.function = reply.function;
    if (reply.kind == codec::ReplyKind::exception) {
        out.kind = "exception";
        out.exception = reply.exception_code;
        return;
    }
    out.kind = "reply";
    out.values = reply.values;
    switch (reply.function) {
        case 1: case 2: case 3: case 4:
            out.count = static_cast<unsigned>(reply.values.size());
            break;
        case 5: case 6:
            out.address = reply.address;
            out.count = 1;
            break;
        default:
            out.address = reply.address;
            out.count = reply.count;
    }
}

// Requests and replies of FC5/6 look alike (the reply echoes); without a direction the frame is
// read as a request first.
void explain_pdu(ByteView pdu, const std::string& direction, FrameExplanation& out) {
    if (pdu.empty()) {
        out.problem = "no function code";
        return;
    }
    std::string request_problem;
    if (direction != "reply" && !(pdu[0] & 0x80)) {
        auto request = codec::decode_request(pdu);
        if (request) return fill_from_request(*request, out);
        request_problem = request.error().message;
        if (direction == "request") {
            out.function = pdu[0];
            out.problem = request_problem;
            return;
        }
    }
    auto reply = codec::decode_reply(pdu);
    if (reply) return fill_from_reply(*reply, out);
    out.function = pdu[0] & 0x7F;
    out.problem = request_problem.empty() ? reply.error().message
                                          : fmt::format("not a valid request ({}) nor reply ({})", request_problem, reply.error().message);
}

void explain_rtu(ByteView wire, const std::string& direction, FrameExplanation& out) {
    if (wire.size() < 4) {
        out.problem = fmt::format("an RTU frame has at least 4 bytes (unit, function, CRC); this one has {}", wire.size());
        return;
    }
    out.unit = wire[0];
    const std::uint16_t computed = codec::crc16(wire.first(wire.size() - 2));
    const std::uint16_t carried = static_cast<std::uint16_t>(wire[wire.size() - 2] | (wire[wire.size() - 1] << 8));
    out.check_ok = computed == carried;
    explain_pdu(wire.subspan(1, wire.size() - 3), direction, out);
    if (!out.check_ok) {
        out.problem = fmt::format("CRC mismatch: computed {:02X} {:02X}, the frame carries {:02X} {:02X}",
                                  computed & 0xFF, computed >> 8, carried & 0xFF, carried >> 8);
    }
}

void explain_ascii(ByteView wire, const std::string& direction, FrameExplanation& out) {
    codec::AsciiDecoder decoder;
    auto events = decoder.feed(wire);
    for (const auto& event : events) {
        if (const auto* discarded = std::get_if<codec::DiscardedBytes>(&event)) {
            out.problem = discarded->reason;
            return;
        }
        const auto& frame = std::get<codec::Frame>(event);
        out.unit = frame.unit;
        out.check_ok = true;
        explain_pdu(frame.pdu, direction, out);
        return;
    }
    out.problem = "no complete ASCII frame (':' ... CR LF)";
}

void explain_tcp(ByteView wire, const std::string& direction, FrameExplanation& out) {
    codec::MbapDecoder decoder;
    auto frames = decoder.feed(wire);
    if (!frames) {
        out.problem = frames.error().message;
        return;
    }
    if (frames->size() != 1 || decoder.buffered() != 0) {
        out.problem = fmt::format("expected exactly one MBAP frame; found {} with {} bytes left over", frames->size(), decoder.buffered());
        return;
    }
    const auto& frame = frames->front();
    out.unit = frame.unit;
    out.transaction = frame.transaction;
    out.check_ok = true;  // TCP carries no check bytes; the header's length was consistent
    explain_pdu(frame.pdu, direction, out);
}

void explain_linking(ByteView wire, const std::string& direction, FrameExplanation& out) {
    const bool reply = direction == "reply" || (direction.empty() && wire.size() == codec::linking_reply_size);
    const std::size_t expected = reply ? codec::linking_reply_size : codec::linking_request_size;
    if (wire.size() != expected) {
        out.problem = fmt::format("a Linking {} has {} bytes; this one has {}", reply ? "reply" : "request", expected, wire.size());
        return;
    }
    // The sum covers Command through Data: the reply's 07h header is not included (§6.7.1).
    const std::size_t first = reply ? 1 : 0;
    out.check_ok = codec::linking_sum(wire.subspan(first, expected - 1 - first)) == wire[expected - 1];
    out.kind = reply ? "reply" : "request";
    if (reply) {
        auto decoded = codec::decode_linking_reply(wire);
        out.unit = wire[2];
        out.address = read_be16(wire, 3);
        out.values = {read_be16(wire, 5)};
        if (!decoded) out.problem = decoded.error().message;
        return;
    }
    auto decoded = codec::decode_linking_request(wire);
    out.command = std::string(1, static_cast<char>(wire[0]));
    out.unit = wire[1];
    out.address = read_be16(wire, 2);
    out.values = {read_be16(wire, 4)};
    if (!decoded) out.problem = decoded.error().message;
}

}  // namespace

Result<FrameExplanation> explain_frame(const std::string& protocol, const std::string& direction, ByteView wire) {
    FrameExplanation out;
    out.protocol = protocol;
    if (protocol == "rtu") explain_rtu(wire, direction, out);
    else if (protocol == "ascii") explain_ascii(wire, direction, out);
    else if (protocol == "tcp") explain_tcp(wire, direction, out);
    else if (protocol == "linking") explain_linking(wire, direction, out);
    else return make_error(ErrorKind::usage, fmt::format("unknown protocol '{}': choose rtu, ascii, tcp or linking", protocol));
    return out;
}

nlohmann::ordered_json to_json(const FrameExplanation& e) {
    const auto optional = [](const auto& value) { return value ? nlohmann::ordered_json(*value) : nlohmann::ordered_json(nullptr); };
    nlohmann::ordered_json out{{"protocol", e.protocol},
                       {"unit", optional(e.unit)},
                       {"function", optional(e.function)},
                       {"kind", e.kind.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(e.kind)},
                       {"address", optional(e.address)},
                       {"count", optional(e.count)},
                       {"values", e.values},
                       {"exception", optional(e.exception)},
                       {"check_ok", e.check_ok},
                       {"error", e.problem.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(e.problem)}};
    if (e.exception) {
        auto name = codec::exception_name(static_cast<std::uint8_t>(*e.exception));
        out["exception_name"] = name ? nlohmann::ordered_json(*name) : nlohmann::ordered_json(nullptr);
    }
    if (e.protocol == "tcp") out["transaction"] = optional(e.transaction);
    if (e.protocol == "linking") out["command"] = optional(e.command);
    return out;
}

}  // namespace loopwire::app
