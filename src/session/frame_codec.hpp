#pragma once
// One interface over the four framings, so master and slave sessions are written once.
// Each implementation wraps a sans-I/O codec from codec/.
#include <memory>
#include <optional>

#include "codec/frame.hpp"
#include "codec/pdu.hpp"
#include "common/result.hpp"
#include "transport/link_url.hpp"

namespace loopwire::session {

class FrameCodec {
public:
    virtual ~FrameCodec() = default;
    // The application data unit for `pdu` addressed to `unit`. `transaction` is used by TCP only.
    virtual Result<Bytes> encode(std::uint8_t unit, ByteView pdu, std::uint16_t transaction) = 0;
    // Bytes that arrived at `arrival`. An error means the stream cannot be resynchronised
    // (MBAP header garbage) and the connection should be dropped.
    virtual Result<codec::FrameEvents> feed(ByteView bytes, Instant arrival) = 0;
    // Set when feed() returned the frames that preceded a header that cannot be resynchronised
    // (MBAP): answer those, then drop the connection. Later feed() calls return the error.
    virtual std::optional<Error> stream_error() const { return std::nullopt; }
    // The line has been quiet until `now` (RTU completes or drops a pending frame).
    virtual codec::FrameEvents flush(Instant /*now*/) { return {}; }
    // When flush() should next be called, if bytes are pending.
    virtual std::optional<Instant> flush_deadline() const { return std::nullopt; }
    virtual void reset() = 0;
};

// `direction`: what this side receives (a slave decodes requests, a master replies).
// `linking_ram_only`: Linking masters send single-register writes as M (RAM only) instead of
// W (RAM and EEPROM).
std::unique_ptr<FrameCodec> make_frame_codec(const transport::LinkUrl& link,
                                             codec::Direction direction,
                                             bool linking_ram_only = false);

}  // namespace loopwire::session
