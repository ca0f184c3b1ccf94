#pragma once
// Modbus TCP framing (Modbus Messaging on TCP/IP V1.0b, 3.1.3): the MBAP header
// (transaction id, protocol id 0, length, unit id) in front of the PDU.
#include <cstdint>
#include <optional>

#include "codec/frame.hpp"
#include "common/result.hpp"

namespace loopwire::codec {

Bytes mbap_encode(std::uint16_t transaction, std::uint8_t unit, ByteView pdu);
// The same ADU appended to `out`: a server queueing replies reuses one buffer.
void mbap_append(Bytes& out, std::uint16_t transaction, std::uint8_t unit, ByteView pdu);

// The largest MBAP length field the decoder still trusts to delimit a frame. A PDU has at most
// 253 bytes (application protocol V1.1b3, 4.1), so a well-formed length is 2..254. Lengths up to
// 260 -- the size of the largest TCP ADU (Messaging on TCP/IP V1.0b, 4.1), the figure a client
// that miscounts would most likely produce -- are still framed by their length, so the frame can
// be skipped and refused (exception 3) while the stream stays in step. Past 260 the peer is not
// speaking Modbus and nothing it says can be trusted.
inline constexpr std::uint16_t mbap_max_trusted_length = 260;

// Streaming MBAP decoder: handles partial reads and several frames in one read.
//
// A frame whose length field is 255..mbap_max_trusted_length is delimited by its length and
// handed out with its over-long PDU (more than max 253 bytes): the receiver refuses it.
//
// A header with a protocol id other than 0 or a length outside 2..mbap_max_trusted_length
// cannot be resynchronised on a byte stream. When complete frames precede it in the same
// feed(), they are returned and broken() names the error, so the receiver can answer them
// before it closes the connection; otherwise feed() returns the error (ErrorKind::malformed).
// Either way every later feed() returns the error, until reset().
class MbapDecoder {
public:
    Result<std::vector<Frame>> feed(ByteView bytes);
    void reset() {
        buffer_.clear();
        broken_.reset();
    }
    std::size_t buffered() const { return buffer_.size(); }
    // Set once a bad header has been seen: the stream must be closed.
    const std::optional<Error>& broken() const { return broken_; }

private:
    Bytes buffer_;
    std::optional<Error> broken_;
};

}  // namespace loopwire::codec
