#pragma once
// The slave side: serves one or more unit ids on a link and keeps the silence rules every
// manual shares: bad check bytes -> no reply (the framer drops the frame); a frame for another
// unit -> no reply; broadcast (unit 0) -> executed by every unit, no reply.
#include <atomic>
#include <map>
#include <memory>
#include <stop_token>

#include "common/result.hpp"
#include "session/frame_codec.hpp"
#include "session/trace.hpp"
#include "session/unit_handler.hpp"
#include "transport/byte_stream.hpp"
#include "transport/link_url.hpp"
#include "transport/tcp.hpp"

namespace loopwire::session {

struct SlaveConnection;  // one accepted TCP client and its framer

using UnitMap = std::map<std::uint8_t, std::shared_ptr<UnitHandler>>;

struct SlaveOptions {
    TraceSink trace;
};

class Slave {
public:
    Slave(transport::LinkUrl link, UnitMap units, SlaveOptions options = {});

    // Serves requests arriving on one byte stream (serial port, pseudo-terminal, virtual bus
    // port, one TCP connection) until `stop` is requested or the stream fails.
    Result<void> serve_stream(transport::ByteStream& stream, std::stop_token stop);

    // Serves every connection `listener` accepts (tcp and rtu+tcp links) until `stop`.
    Result<void> serve_listener(transport::TcpListener& listener, std::stop_token stop);

    // The reply frame (wire bytes) for one received frame, or nullopt for silence.
    std::optional<Bytes> answer(const codec::Frame& frame, FrameCodec& codec);

    // Requests served and replies sent so far (for status lines and tests).
    std::uint64_t requests_served() const { return requests_; }

private:
    void trace(TraceDirection direction, ByteView bytes, std::string note) const;
    void flush_quiet(SlaveConnection& connection);
    void reply_after_silence(transport::ByteStream& stream, const Bytes& reply, Instant request_end);

    transport::LinkUrl link_;
    UnitMap units_;
    SlaveOptions options_;
    std::atomic<std::uint64_t> requests_{0};
};

}  // namespace loopwire::session
