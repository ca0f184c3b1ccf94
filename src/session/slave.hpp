#pragma once
// The slave side: serves one or more unit ids on a link and keeps the silence rules every
// manual shares: bad check bytes -> no reply (the framer drops the frame); a frame for another
// unit -> no reply; broadcast (unit 0) -> executed by every unit, no reply.
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stop_token>
#include <string>
#include <vector>

#include "common/clock.hpp"
#include "common/result.hpp"
#include "session/frame_codec.hpp"
#include "session/trace.hpp"
#include "session/unit_handler.hpp"
#include "transport/address_allow_list.hpp"
#include "transport/byte_stream.hpp"
#include "transport/link_url.hpp"
#include "transport/tcp.hpp"

namespace boost::asio {
class io_context;
}

namespace loopwire::session {

using UnitMap = std::map<std::uint8_t, std::shared_ptr<UnitHandler>>;

// How much one TCP client may cost the others (serve_listener).
struct TcpClientLimits {
    // Replies queued for a client that does not read them: past this the connection is closed,
    // so a stalled or hostile client costs bounded memory and never delays anyone else.
    std::size_t max_queued_reply_bytes = 64 * 1024;
    // Requests handed to deferring handlers and not answered yet: at this many, the requests
    // that came in the same read wait in the connection (one read's worth of bytes at most) and
    // the socket is not read again until one is answered. A pipelining client waits in its own
    // socket buffer instead of growing a queue behind the handlers.
    std::size_t max_outstanding_requests = 32;
    // Connections open at once; 0: no limit. A client connecting when this many are open is
    // admitted by closing the one idle longest (a client that has ended its side first, then one
    // that never sent a whole request, then the least recently active), so idle sockets never
    // lock a working client out. When every connection has a request in progress, the newcomer
    // is closed instead: each of those is a client being served.
    std::size_t max_connections = 0;
    // A connection that has received nothing and has had no request in progress for this long
    // is closed; zero: never. A request waiting for a slow handler does not count as idle.
    std::chrono::milliseconds idle_timeout{0};
    // After accept() fails for lack of resources (EMFILE, ENFILE, ENOBUFS, ENOMEM) the waiting
    // client stays queued in the kernel; retrying at once would spin, so accepting pauses.
    std::chrono::milliseconds accept_retry_delay{100};
};

// Who may use the TCP side of a slave, by address (a gateway's [modbus_tcp] allow and
// write_allow). Empty lists: everyone.
struct TcpAccess {
    transport::AddressAllowList allow;        // others are closed at accept, counted
    transport::AddressAllowList write_allow;  // others reach the units with Asker::may_write false
};

// What the TCP side of a slave has done with its connections (serve_listener).
struct TcpConnectionStatistics {
    std::uint64_t accepted = 0;
    std::uint64_t not_allowed = 0;  // closed at accept: the address is outside TcpAccess::allow
    std::uint64_t evicted = 0;      // closed to admit a newcomer at max_connections
    std::uint64_t refused = 0;      // newcomers closed at once: every connection was busy
    std::uint64_t idle_closed = 0;  // closed after idle_timeout
    std::uint64_t open = 0;         // open now
};

struct SlaveOptions {
    TraceSink trace;
    // One line for each connection the TCP limits close (evicted, refused, idle), for a log at
    // debug level: under a flood these come by the thousand.
    std::function<void(const std::string&)> connection_log;
    TcpClientLimits tcp;
    TcpAccess access;
    // What a TCP client addressing a unit nobody serves gets at once, instead of waiting for a
    // timeout (on a serial line other units may share the wire, so silence is the rule there).
    // Modbus application protocol V1.1b3, 7: 0Bh "gateway target device failed to respond"
    // for a simulator, 0Ah "gateway path unavailable" for a gateway with no line to the unit.
    std::uint8_t unserved_unit_exception = 0x0B;
    // What serve_stream's reply gap and frame timing run on (common/clock.hpp). A virtual clock
    // only makes sense with a stream that reads the same clock. TCP listeners keep the steady
    // clock.
    std::shared_ptr<Clock> clock = steady_clock();
};

class Slave {
public:
    Slave(transport::LinkUrl link, UnitMap units, SlaveOptions options = {});

    // Serves requests arriving on one byte stream (serial port, pseudo-terminal, virtual bus
    // port, one TCP connection) until `stop` is requested or the stream fails.
    Result<void> serve_stream(transport::ByteStream& stream, std::stop_token stop);

    // A reply frame and when it may go on the wire.
    struct TimedReply {
        Instant not_before;
        Bytes frame;
    };

    // Serving one byte stream as steps, without reading or waiting: what serve_stream does on a
    // thread of its own, and what a loop serving several streams on one thread does for each
    // (simulation/simulated_lines.hpp). The caller reads, hands what it read to heard(), calls
    // heard() with nothing once flush_deadline() has passed, and sends each reply at its time.
    class StreamSteps {
    public:
        explicit StreamSteps(Slave& slave);
        // `bytes` arrived at `now` (empty: the line was quiet until `now`): the replies they
        // call for. An error: the stream cannot be resynchronised (MBAP garbage); broken()
        // says the same after the frames before the garbage were answered.
        Result<std::vector<TimedReply>> heard(ByteView bytes, Instant now);
        std::optional<Instant> flush_deadline() const { return codec_->flush_deadline(); }
        std::optional<Error> broken() const { return codec_->stream_error(); }
        // Traces a reply as it goes on the wire.
        void sending(const TimedReply& reply) const;

    private:
        Slave& slave_;
        std::unique_ptr<FrameCodec> codec_;
    };

    // Serves every connection `listener` accepts (tcp and rtu+tcp links) until `stop`, all on
    // one event loop (session/tcp_slave_server.hpp).
    Result<void> serve_listener(transport::TcpListener& listener, std::stop_token stop);
    // The same on the caller's event loop, run by this thread until the serving ends, and shared
    // with whatever else the caller posts to it (a gateway's engine, gateway/engine.hpp). The
    // loop is stopped when the serving ends; what is still queued on it is the caller's.
    Result<void> serve_listener(transport::TcpListener& listener, std::stop_token stop, boost::asio::io_context& loop);

    // The reply frame (wire bytes) for one received frame, or nullopt for silence.
    std::optional<Bytes> answer(const codec::Frame& frame, FrameCodec& codec);

    // The reply PDU for one received frame through `reply` (nullopt: silence), at once or later
    // from any thread when the unit's handler defers it (UnitHandler::handle_async).
    void answer_async(codec::Frame frame, const UnitHandler::Asker& asker, UnitHandler::ReplyCallback reply);

    // Serves `units` from the next request on, from any thread: a gateway reopened with a new
    // configuration keeps its Modbus TCP front and the clients' connections. A request already
    // handed to a unit is answered by it.
    void replace_units(UnitMap units);

    // Requests served and replies sent so far (for status lines and tests).
    std::uint64_t requests_served() const { return requests_; }

    // The TCP connections' figures so far; safe from any thread while serve_listener runs.
    TcpConnectionStatistics tcp_statistics() const;
    enum class ConnectionEvent { accepted, not_allowed, evicted, refused, idle_closed, closed };
    // Counted by the TCP server (session/tcp_slave_server.cpp) as they happen.
    void count(ConnectionEvent event);

    const transport::LinkUrl& link() const { return link_; }
    const SlaveOptions& options() const { return options_; }
    bool tracing() const { return static_cast<bool>(options_.trace); }
    Clock& clock() const { return *clock_; }
    // Callers check tracing() first, so nothing is formatted when nobody listens.
    void trace(TraceDirection direction, ByteView bytes, std::string note) const;

private:
    // Where one frame goes: to a unit's handler, or answered (or not) by the slave itself.
    struct Route {
        enum class Kind { silent, own_reply, unit, broadcast } kind = Kind::silent;
        std::shared_ptr<const UnitMap> units;  // the map routed by, holding its handlers
        UnitHandler* handler = nullptr;        // Kind::unit
        Bytes reply_pdu;                       // Kind::own_reply
    };
    Route route(const codec::Frame& frame);
    std::shared_ptr<const UnitMap> units() const;
    // When a reply to a request that ended at `request_end` may go (serial lines keep a gap).
    Instant reply_time(Instant request_end) const;

    transport::LinkUrl link_;
    mutable std::mutex units_mutex_;  // guards the pointer; the map it points to never changes
    std::shared_ptr<const UnitMap> units_;
    SlaveOptions options_;
    std::shared_ptr<Clock> clock_;
    std::atomic<std::uint64_t> requests_{0};
    std::atomic<std::uint64_t> accepted_{0};
    std::atomic<std::uint64_t> not_allowed_{0};
    std::atomic<std::uint64_t> evicted_{0};
    std::atomic<std::uint64_t> refused_{0};
    std::atomic<std::uint64_t> idle_closed_{0};
    std::atomic<std::uint64_t> closed_{0};
};

}  // namespace loopwire::session
