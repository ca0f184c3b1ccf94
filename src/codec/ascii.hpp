#pragma once
// Modbus ASCII framing (Modbus over serial line V1.02, 2.5.2): ':' + hex(unit, PDU, LRC) + CR LF.
#include <cstdint>

#include "codec/frame.hpp"

namespace loopwire::codec {

// Two's complement of the 8-bit sum of the bytes (unit through end of data).
std::uint8_t lrc(ByteView bytes);

// Upper-case hex, as the spec and the ramp/soak manual (chapter 5) print it.
Bytes ascii_encode(std::uint8_t unit, ByteView pdu);

// Streaming ASCII decoder: a ':' always starts a new frame (discarding any partial one),
// CR LF ends it. Upper- and lower-case hex accepted. With 7 data bits the eighth bit of every
// byte is ignored (some adapters leave the parity bit in it).
class AsciiDecoder {
public:
    explicit AsciiDecoder(unsigned data_bits = 8);
    FrameEvents feed(ByteView bytes);
    void reset();

private:
    unsigned data_bits_;
    Bytes pending_;      // characters after ':'
    bool in_frame_ = false;
    Bytes noise_;        // characters outside any frame
};

}  // namespace loopwire::codec
