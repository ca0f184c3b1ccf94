#pragma once
// A byte pipe: serial port, pseudo-terminal, TCP connection or a port on the virtual bus.
// Transports know nothing of frames.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <span>
#include <string>

#include "common/bytes.hpp"
#include "common/result.hpp"

namespace loopwire::transport {

using std::chrono::milliseconds;

enum class Parity { none, even, odd };

// Kernel RS-485 direction control (TIOCSRS485): off; on, where a port whose driver lacks it
// fails to open; or if_supported ("auto"), where such a port runs without it and says so when
// it opens.
enum class Rs485 { off, on, if_supported };

// Silence kept on a serial line before each frame, beyond the 3.5 characters RTU needs: in
// characters at the line's speed ("3.5c") or as a time ("5ms"). Zero: none beyond the 3.5.
struct LineGuard {
    double characters = 0;
    std::chrono::microseconds time{0};

    bool operator==(const LineGuard&) const = default;
};

// Character format and speed of a serial line (also stored on pseudo-terminals, which ignore it).
struct SerialSettings {
    std::uint32_t baud = 19200;
    unsigned data_bits = 8;
    Parity parity = Parity::even;
    unsigned stop_bits = 1;
    Rs485 rs485 = Rs485::off;  // ask the kernel to drive the RS-485 transmitter (TIOCSRS485)
    // RTS raised this long before the first bit and held this long after the last (whole
    // milliseconds: what struct serial_rs485 carries), for transceivers slow to turn around.
    milliseconds rs485_delay_before{0};
    milliseconds rs485_delay_after{0};
    LineGuard guard;

    // 1 start bit + data + parity + stop: what one character costs on the wire.
    unsigned bits_per_character() const {
        return 1 + data_bits + (parity == Parity::none ? 0 : 1) + stop_bits;
    }
    // The guard as a time at this speed.
    std::chrono::microseconds guard_time() const {
        const double per_character_us = 1e6 * bits_per_character() / baud;
        const auto from_characters = std::chrono::microseconds(static_cast<long long>(guard.characters * per_character_us + 0.5));
        return std::max(guard.time, from_characters);
    }
};

class ByteStream {
public:
    virtual ~ByteStream() = default;
    ByteStream() = default;
    ByteStream(const ByteStream&) = delete;
    ByteStream& operator=(const ByteStream&) = delete;

    // Writes every byte (blocking until the kernel took them all) or fails with ErrorKind::link.
    virtual Result<void> write(ByteView bytes) = 0;
    // For a loop that carries several lines on one thread (session/line_loop.hpp): hands the
    // bytes over without waiting for them to leave the wire, and returns when the last one will
    // have left, for the caller to wait out on its own timer. A stream without a wire time of its
    // own writes as write() does and returns the time it returned.
    virtual Result<Instant> write_without_waiting(ByteView bytes) {
        if (auto written = write(bytes); !written) return written.error();
        return std::chrono::steady_clock::now();
    }
    // Writes every byte if the kernel takes them all now, without waiting for room in its
    // buffer: for a sender on a loop that one peer must not hold (a Modbus TCP device that
    // stopped reading its connection would hold the gateway's engine). A full buffer fails it
    // with ErrorKind::link, and part of the bytes may have gone: the caller drops the stream.
    // A stream without a buffer of its own writes as write() does.
    virtual Result<void> write_now(ByteView bytes) { return write(bytes); }
    // Waits up to `timeout` for bytes; returns how many were stored in `buffer` (0 = timeout).
    // A closed peer is ErrorKind::link ("connection closed by peer").
    virtual Result<std::size_t> read_some(std::span<std::uint8_t> buffer, milliseconds timeout) = 0;
    // Discards whatever is waiting to be read (stale replies before a new request).
    virtual void discard_input() = 0;
    // A file descriptor that becomes readable when read_some would not block (for poll()-based
    // event loops); -1 where there is none.
    virtual int poll_handle() const = 0;
    // "rtu:/dev/ttyUSB0", "tcp 127.0.0.1:502" — for messages.
    virtual std::string describe() const = 0;
};

}  // namespace loopwire::transport
