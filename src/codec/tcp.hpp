#pragma once
// Modbus TCP framing (Modbus Messaging on TCP/IP V1.0b, 3.1.3): the MBAP header
// (transaction id, protocol id 0, length, unit id) in front of the PDU.
#include <cstdint>

#include "codec/frame.hpp"
#include "common/result.hpp"

namespace loopwire::codec {

Bytes mbap_encode(std::uint16_t transaction, std::uint8_t unit, ByteView pdu);

// Streaming MBAP decoder: handles partial reads and several frames in one read. A header with a
// protocol id other than 0 or a length outside 2..254 (unit + at most 253 PDU bytes) cannot be
// resynchronised on a byte stream: feed() returns ErrorKind::malformed and the connection
// should be closed.
class MbapDecoder {
public:
    Result<std::vector<Frame>> feed(ByteView bytes);
    void reset() { buffer_.clear(); }
    std::size_t buffered() const { return buffer_.size(); }

private:
    Bytes buffer_;
};

}  // namespace loopwire::codec
