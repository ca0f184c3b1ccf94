#include "session/slave.hpp"

#include <poll.h>

#include <list>
#include <thread>

#include <fmt/format.h>

#include "codec/rtu.hpp"

namespace loopwire::session {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

// Exception 0Bh: "gateway target device failed to respond" (Modbus application protocol
// V1.1b3, 7). On TCP a client addressing a unit nobody serves learns so at once instead of
// waiting for a timeout; on a serial line other units may share the wire, so silence is the rule.
constexpr std::uint8_t gateway_target_failed = 0x0B;
// Modbus Messaging on TCP/IP Implementation Guide V1.0b, 4.4.2: a server that is not a gateway
// should accept unit FFh as "this server". With one unit served, FFh reaches it.
constexpr std::uint8_t tcp_direct_unit = 0xFF;

milliseconds until(std::optional<Instant> deadline, milliseconds longest) {
    if (!deadline) return longest;
    auto left = std::chrono::ceil<milliseconds>(*deadline - Clock::now());
    return std::clamp(left, milliseconds(0), longest);
}

}  // namespace

Slave::Slave(transport::LinkUrl link, UnitMap units, SlaveOptions options)
    : link_(std::move(link)), units_(std::move(units)), options_(std::move(options)) {}

void Slave::trace(TraceDirection direction, ByteView bytes, std::string note) const {
    if (options_.trace) options_.trace({Clock::now(), direction, Bytes(bytes.begin(), bytes.end()), std::move(note)});
}

std::optional<Bytes> Slave::answer(const codec::Frame& frame, FrameCodec& codec) {
    if (frame.pdu.empty()) return std::nullopt;
    if (frame.unit == 0) {
        trace(TraceDirection::received, frame.raw, "broadcast: executed by every unit, not answered");
        for (auto& [unit, handler] : units_) handler->handle(frame.pdu, true);
        ++requests_;
        return std::nullopt;
    }
    auto it = units_.find(frame.unit);
    if (it == units_.end() && frame.unit == tcp_direct_unit && link_.framing == transport::Framing::tcp && units_.size() == 1) {
        it = units_.begin();
    }
    if (it == units_.end()) {
        trace(TraceDirection::received, frame.raw, fmt::format("unit {} is not served here", frame.unit));
        if (link_.framing != transport::Framing::tcp) return std::nullopt;
        Bytes pdu{static_cast<std::uint8_t>(frame.pdu[0] | 0x80), gateway_target_failed};
        auto encoded = codec.encode(frame.unit, pdu, frame.transaction);
        return encoded ? std::optional<Bytes>(std::move(*encoded)) : std::nullopt;
    }
    trace(TraceDirection::received, frame.raw, fmt::format("request for unit {}", frame.unit));
    ++requests_;
    auto reply_pdu = it->second->handle(frame.pdu, false);
    if (!reply_pdu) {
        trace(TraceDirection::discarded, frame.raw, "unit stays silent");
        return std::nullopt;
    }
    auto encoded = codec.encode(frame.unit, *reply_pdu, frame.transaction);
    if (!encoded) {
        trace(TraceDirection::discarded, *reply_pdu, "reply not sent: " + encoded.error().message);
        return std::nullopt;
    }
    return std::move(*encoded);
}

// A serial-line slave may only answer once the request has ended, i.e. after 3.5 characters of
// silence (Modbus over serial line V1.02, 2.5.1.1). Frames found by length end earlier than
// that, so the reply waits out the rest of the gap.
void Slave::reply_after_silence(transport::ByteStream& stream, const Bytes& reply, Instant request_end) {
    if (link_.is_serial()) {
        const auto gap = codec::CharacterTiming{link_.serial.baud, link_.serial.bits_per_character()}.t3_5();
        std::this_thread::sleep_until(request_end + gap);
    }
    trace(TraceDirection::sent, reply, "reply");
    (void)stream.write(reply);  // a failed write surfaces as a read error on the next turn
}

Result<void> Slave::serve_stream(transport::ByteStream& stream, std::stop_token stop) {
    auto codec = make_frame_codec(link_, codec::Direction::request);
    std::array<std::uint8_t, 1024> buffer{};
    while (!stop.stop_requested()) {
        auto got = stream.read_some(buffer, until(codec->flush_deadline(), milliseconds(100)));
        if (!got) return got.error();
        const auto now = Clock::now();
        codec::FrameEvents events;
        if (*got > 0) {
            auto fed = codec->feed(ByteView(buffer.data(), *got), now);
            if (!fed) return fed.error();
            events = std::move(*fed);
        } else {
            events = codec->flush(now);
        }
        for (const auto& event : events) {
            if (const auto* discarded = std::get_if<codec::DiscardedBytes>(&event)) {
                trace(TraceDirection::discarded, discarded->bytes, discarded->reason);
                continue;
            }
            if (auto reply = answer(std::get<codec::Frame>(event), *codec)) reply_after_silence(stream, *reply, now);
        }
    }
    return {};
}

struct SlaveConnection {
    std::unique_ptr<transport::ByteStream> stream;
    std::unique_ptr<FrameCodec> codec;
};

// RTU frames through a device server whose function code gives no length end by silence.
void Slave::flush_quiet(SlaveConnection& connection) {
    auto deadline = connection.codec->flush_deadline();
    if (!deadline || *deadline > Clock::now()) return;
    for (const auto& event : connection.codec->flush(Clock::now())) {
        if (const auto* frame = std::get_if<codec::Frame>(&event)) {
            if (auto reply = answer(*frame, *connection.codec)) {
                trace(TraceDirection::sent, *reply, "reply");
                (void)connection.stream->write(*reply);
            }
        }
    }
}

Result<void> Slave::serve_listener(transport::TcpListener& listener, std::stop_token stop) {
    std::list<SlaveConnection> connections;
    std::array<std::uint8_t, 4096> buffer{};
    std::vector<pollfd> fds;
    while (!stop.stop_requested()) {
        fds.assign(1, pollfd{listener.poll_handle(), POLLIN, 0});
        for (auto& c : connections) fds.push_back(pollfd{c.stream->poll_handle(), POLLIN, 0});
        if (::poll(fds.data(), fds.size(), 20) <= 0) {
            for (auto& c : connections) flush_quiet(c);
            continue;
        }
        std::size_t index = 1;
        for (auto it = connections.begin(); it != connections.end(); ++index) {
            if (!(fds[index].revents & (POLLIN | POLLHUP | POLLERR))) { ++it; continue; }
            auto got = it->stream->read_some(buffer, milliseconds(0));
            bool keep = got.ok();
            if (keep && *got > 0) {
                auto events = it->codec->feed(ByteView(buffer.data(), *got), Clock::now());
                keep = events.ok();
                if (!events) trace(TraceDirection::discarded, ByteView(buffer.data(), *got), events.error().message + "; connection closed");
                for (const auto& event : keep ? *events : codec::FrameEvents{}) {
                    if (const auto* frame = std::get_if<codec::Frame>(&event)) {
                        if (auto reply = answer(*frame, *it->codec)) {
                            trace(TraceDirection::sent, *reply, "reply");
                            keep = it->stream->write(*reply).ok();
                        }
                    } else {
                        const auto& discarded = std::get<codec::DiscardedBytes>(event);
                        trace(TraceDirection::discarded, discarded.bytes, discarded.reason);
                    }
                }
            }
            it = keep ? std::next(it) : connections.erase(it);
        }
        for (auto& c : connections) flush_quiet(c);
        if (fds[0].revents & POLLIN) {
            auto client = listener.accept(milliseconds(0));
            if (client && *client) {
                connections.push_back({std::move(*client), make_frame_codec(link_, codec::Direction::request)});
            }
        }
    }
    return {};
}

}  // namespace loopwire::session
