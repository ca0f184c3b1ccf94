#include "session/slave.hpp"

#include <fmt/format.h>

#include "codec/rtu.hpp"
#include "session/tcp_slave_server.hpp"

namespace loopwire::session {
namespace {

using std::chrono::milliseconds;

// Modbus Messaging on TCP/IP Implementation Guide V1.0b, 4.4.2: a server that is not a gateway
// should accept unit FFh as "this server". With one unit served, FFh reaches it.
constexpr std::uint8_t tcp_direct_unit = 0xFF;

// Modbus over serial line V1.02, 2.1: broadcast requests are necessarily writing commands, and
// nobody answers them. A function that only reads or reports (1-4, 7, 8, 11, 12, 17, 20, 23, 24,
// 43) is never one: a Modbus TCP client asking it of unit 0 waits for a reply that would never
// come, so it gets exception 01h at once instead. Vendor functions may write and are passed on.
bool broadcastable(std::uint8_t function) {
    switch (function) {
        case 1: case 2: case 3: case 4: case 7: case 8: case 11: case 12: case 17: case 20: case 23: case 24: case 43:
            return false;
        default: return true;
    }
}

milliseconds until(std::optional<Instant> deadline, Instant now, milliseconds longest) {
    if (!deadline) return longest;
    auto left = std::chrono::ceil<milliseconds>(*deadline - now);
    return std::clamp(left, milliseconds(0), longest);
}

Bytes exception_pdu(std::uint8_t function, std::uint8_t code) {
    return Bytes{static_cast<std::uint8_t>(function | 0x80), code};
}

}  // namespace

Slave::Slave(transport::LinkUrl link, UnitMap units, SlaveOptions options)
    : link_(std::move(link)),
      units_(std::make_shared<const UnitMap>(std::move(units))),
      options_(std::move(options)),
      clock_(options_.clock ? options_.clock : steady_clock()) {}

void Slave::trace(TraceDirection direction, ByteView bytes, std::string note) const {
    if (options_.trace) options_.trace({clock_->now(), direction, Bytes(bytes.begin(), bytes.end()), std::move(note)});
}

void Slave::replace_units(UnitMap units) {
    auto replacement = std::make_shared<const UnitMap>(std::move(units));
    std::lock_guard lock(units_mutex_);
    units_.swap(replacement);
}  // the old map goes here, or with the last request routed by it

std::shared_ptr<const UnitMap> Slave::units() const {
    std::lock_guard lock(units_mutex_);
    return units_;
}

namespace {

// The handler answering at `unit`: the one served under it, unless a request moved a handler
// (UnitHandler::answers_as), which then answers at its new id and no longer at the old one.
UnitMap::const_iterator find_unit(const UnitMap& units, std::uint8_t unit) {
    for (auto it = units.begin(); it != units.end(); ++it) {
        if (it->second->answers_as().value_or(it->first) == unit) return it;
    }
    return units.end();
}

// Every unit that hears the line sees every frame go past, whatever its unit, and bytes that
// failed their check (UnitHandler::line_activity).
void line_activity(const UnitMap& units) {
    for (const auto& [unit, handler] : units) {
        if (handler->answers_as() != std::uint8_t{0}) handler->line_activity();  // 0: does not hear the line
    }
}

}  // namespace

Slave::Route Slave::route(const codec::Frame& frame) {
    Route where;
    where.units = units();
    const UnitMap& units = *where.units;
    line_activity(units);
    if (frame.pdu.empty()) return where;
    if (frame.unit == 0 && link_.framing == transport::Framing::tcp && !broadcastable(frame.pdu[0])) {
        if (tracing()) trace(TraceDirection::received, frame.raw, "unit 0 (broadcast) asks for a reply: refused, exception 01h");
        where.kind = Route::Kind::own_reply;
        where.reply_pdu = exception_pdu(frame.pdu[0], static_cast<std::uint8_t>(codec::ExceptionCode::illegal_function));
        return where;
    }
    if (frame.unit == 0) {
        if (tracing()) trace(TraceDirection::received, frame.raw, "broadcast: executed by every unit, not answered");
        ++requests_;
        where.kind = Route::Kind::broadcast;
        return where;
    }
    auto it = find_unit(units, frame.unit);
    if (it == units.end() && frame.unit == tcp_direct_unit && link_.framing == transport::Framing::tcp && units.size() == 1) {
        it = units.begin();
    }
    if (it == units.end()) {
        if (tracing()) trace(TraceDirection::received, frame.raw, fmt::format("unit {} is not served here", frame.unit));
        if (link_.framing != transport::Framing::tcp) return where;
        where.kind = Route::Kind::own_reply;
        where.reply_pdu = exception_pdu(frame.pdu[0], options_.unserved_unit_exception);
        return where;
    }
    ++requests_;
    // Only an MBAP length of 255..260 yields a PDU past 253 bytes (codec/tcp.hpp): no PDU may be
    // that long (application protocol V1.1b3, 4.1), so it is refused with exception 3 (illegal
    // data value, as for a quantity past the limit in 6.12) without reaching the unit.
    if (frame.pdu.size() > codec::max_pdu_size) {
        if (tracing()) trace(TraceDirection::discarded, frame.raw, fmt::format("PDU of {} bytes is longer than 253: refused", frame.pdu.size()));
        where.kind = Route::Kind::own_reply;
        where.reply_pdu = exception_pdu(frame.pdu[0], static_cast<std::uint8_t>(codec::ExceptionCode::illegal_data_value));
        return where;
    }
    if (tracing()) trace(TraceDirection::received, frame.raw, fmt::format("request for unit {}", frame.unit));
    where.kind = Route::Kind::unit;
    where.handler = it->second.get();
    return where;
}

std::optional<Bytes> Slave::answer(const codec::Frame& frame, FrameCodec& codec) {
    Route where = route(frame);
    std::optional<Bytes> reply_pdu;
    switch (where.kind) {
        case Route::Kind::silent: return std::nullopt;
        case Route::Kind::broadcast:
            for (const auto& [unit, handler] : *where.units) {
                if (handler->answers_as() != std::uint8_t{0}) handler->handle(frame.pdu, true);  // 0: does not hear the line
            }
            return std::nullopt;
        case Route::Kind::own_reply: reply_pdu = std::move(where.reply_pdu); break;
        case Route::Kind::unit: reply_pdu = where.handler->handle(frame.pdu, false); break;
    }
    if (!reply_pdu) {
        if (tracing()) trace(TraceDirection::discarded, frame.raw, "unit stays silent");
        return std::nullopt;
    }
    auto encoded = codec.encode(frame.unit, *reply_pdu, frame.transaction);
    if (!encoded) {
        if (tracing()) trace(TraceDirection::discarded, *reply_pdu, "reply not sent: " + encoded.error().message);
        return std::nullopt;
    }
    return std::move(*encoded);
}

void Slave::answer_async(codec::Frame frame, const UnitHandler::Asker& asker, UnitHandler::ReplyCallback reply) {
    Route where = route(frame);
    switch (where.kind) {
        case Route::Kind::silent: reply(std::nullopt); return;
        case Route::Kind::broadcast:
            // Every unit executes it; whatever they answer, and whenever, is dropped.
            for (const auto& [unit, handler] : *where.units) {
                handler->handle_async(frame.pdu, true, asker, [](std::optional<Bytes>) {});
            }
            reply(std::nullopt);
            return;
        case Route::Kind::own_reply: reply(std::move(where.reply_pdu)); return;
        case Route::Kind::unit: where.handler->handle_async(std::move(frame.pdu), false, asker, std::move(reply)); return;
    }
}

// A serial-line slave may only answer once the request has ended, i.e. after 3.5 characters of
// silence (Modbus over serial line V1.02, 2.5.1.1). Frames found by length end earlier than
// that, so the reply waits out the rest of the gap.
Instant Slave::reply_time(Instant request_end) const {
    if (!link_.is_serial()) return request_end;
    return request_end + codec::CharacterTiming{link_.serial.baud, link_.serial.bits_per_character()}.t3_5();
}

Result<void> Slave::serve_stream(transport::ByteStream& stream, std::stop_token stop) {
    StreamSteps steps(*this);
    std::array<std::uint8_t, 1024> buffer{};
    while (!stop.stop_requested()) {
        auto got = stream.read_some(buffer, until(steps.flush_deadline(), clock_->now(), milliseconds(100)));
        if (!got) return got.error();
        auto replies = steps.heard(ByteView(buffer.data(), *got), clock_->now());
        if (!replies) return replies.error();
        for (const auto& reply : *replies) {
            clock_->sleep_until(reply.not_before);
            steps.sending(reply);
            (void)stream.write(reply.frame);  // a failed write surfaces as a read error on the next turn
        }
        if (auto broken = steps.broken()) return *broken;  // after answering what came before
    }
    return {};
}

Slave::StreamSteps::StreamSteps(Slave& slave)
    : slave_(slave), codec_(make_frame_codec(slave.link_, codec::Direction::request)) {}

Result<std::vector<Slave::TimedReply>> Slave::StreamSteps::heard(ByteView bytes, Instant now) {
    codec::FrameEvents events;
    if (!bytes.empty()) {
        auto fed = codec_->feed(bytes, now);
        if (!fed) return fed.error();
        events = std::move(*fed);
    } else {
        events = codec_->flush(now);
    }
    std::vector<TimedReply> replies;
    for (const auto& event : events) {
        if (const auto* discarded = std::get_if<codec::DiscardedBytes>(&event)) {
            if (slave_.tracing()) slave_.trace(TraceDirection::discarded, discarded->bytes, discarded->reason);
            line_activity(*slave_.units());  // a bad check or noise: still bytes on the line
            continue;
        }
        if (auto reply = slave_.answer(std::get<codec::Frame>(event), *codec_)) {
            replies.push_back({slave_.reply_time(now), std::move(*reply)});
        }
    }
    return replies;
}

void Slave::StreamSteps::sending(const TimedReply& reply) const {
    if (slave_.tracing()) slave_.trace(TraceDirection::sent, reply.frame, "reply");
}

TcpConnectionStatistics Slave::tcp_statistics() const {
    TcpConnectionStatistics statistics;
    statistics.accepted = accepted_.load(std::memory_order_relaxed);
    statistics.not_allowed = not_allowed_.load(std::memory_order_relaxed);
    statistics.evicted = evicted_.load(std::memory_order_relaxed);
    statistics.refused = refused_.load(std::memory_order_relaxed);
    statistics.idle_closed = idle_closed_.load(std::memory_order_relaxed);
    const auto closed = closed_.load(std::memory_order_relaxed);
    statistics.open = statistics.accepted > closed ? statistics.accepted - closed : 0;  // read apart: may cross
    return statistics;
}

void Slave::count(ConnectionEvent event) {
    switch (event) {
        case ConnectionEvent::accepted: ++accepted_; return;
        case ConnectionEvent::not_allowed: ++not_allowed_; return;
        case ConnectionEvent::evicted: ++evicted_; return;
        case ConnectionEvent::refused: ++refused_; return;
        case ConnectionEvent::idle_closed: ++idle_closed_; return;
        case ConnectionEvent::closed: ++closed_; return;
    }
}

Result<void> Slave::serve_listener(transport::TcpListener& listener, std::stop_token stop) {
    return serve_tcp_clients(*this, listener, std::move(stop));
}

Result<void> Slave::serve_listener(transport::TcpListener& listener, std::stop_token stop, boost::asio::io_context& loop) {
    return serve_tcp_clients(*this, listener, std::move(stop), &loop);
}

}  // namespace loopwire::session
