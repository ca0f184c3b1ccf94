#pragma once
// Modbus RTU framing (Modbus over serial line V1.02, 2.5): unit + PDU + CRC-16, low byte first.
#include <chrono>
#include <cstdint>

#include "codec/frame.hpp"
#include "codec/pdu.hpp"

namespace loopwire::codec {

// CRC-16/MODBUS: polynomial A001h (reflected 8005h), initial value FFFFh. The result's low byte
// is sent first.
std::uint16_t crc16(ByteView bytes);

Bytes rtu_encode(std::uint8_t unit, ByteView pdu);

// Character timing of a serial line: 1 start bit + data bits + parity bit + stop bits.
struct CharacterTiming {
    std::uint32_t baud = 19200;
    unsigned bits_per_character = 11;

    std::chrono::microseconds character_time() const;
    // 1.5 and 3.5 character times; above 19200 baud the fixed 750 us and 1750 us the serial-line
    // spec recommends (Modbus over serial line V1.02, 2.5.1.1).
    std::chrono::microseconds t1_5() const;
    std::chrono::microseconds t3_5() const;
};

// Streaming RTU decoder. It delimits frames two ways at once:
//  - by silence: a gap of more than 3.5 character times ends a frame;
//  - by length: the function code implies the frame length (expected_pdu_length), so frames
//    are found even where timing is lost (pseudo-terminals, serial device servers over TCP).
// A candidate frame whose CRC does not match is not dropped whole: the decoder slides one byte
// and tries again, so it resynchronises after noise. Every discarded run is reported once.
class RtuDecoder {
public:
    RtuDecoder(Direction direction, CharacterTiming timing);

    // Bytes that arrived together at `arrival`.
    FrameEvents feed(ByteView bytes, Instant arrival);
    // Tell the decoder that the line has been quiet until `now`: pending bytes older than 3.5
    // characters are completed into a frame (if the CRC checks) or discarded; a frame under way
    // (its function code gives a length not yet reached) is given up to 20 ms, as readers get
    // bytes in batches.
    FrameEvents flush(Instant now);
    void reset();
    std::size_t buffered() const { return buffer_.size(); }
    // When the pending bytes become stale (last arrival + the silence that flush() needs), if
    // any: flush() at or after it judges them.
    std::optional<Instant> silence_deadline() const;

private:
    FrameEvents drain(bool line_quiet);
    std::chrono::microseconds silence_needed() const;
    bool frame_runs_on(ByteView bytes) const;
    void extend_discard_run(std::uint8_t byte, FrameEvents& events);
    void report_discard_run(FrameEvents& events);

    Direction direction_;
    CharacterTiming timing_;
    Bytes buffer_;
    Instant last_arrival_{};
    // Bytes already given up on while later bytes are still buffered: held back so that one
    // run of noise is reported as one event, with the reason its first byte was dropped.
    DiscardedBytes discard_run_;
};

}  // namespace loopwire::codec
