#include "codec/ascii.hpp"

#include <algorithm>
#include <string>

namespace loopwire::codec {

namespace {

constexpr std::uint8_t frame_start = ':';
constexpr std::uint8_t carriage_return = '\r';
constexpr std::uint8_t line_feed = '\n';

// Modbus over serial line V1.02, 2.5.2.1: an ASCII frame is at most 513 characters:
// ':' + 2 x (unit + 253 PDU bytes + LRC) + CR LF. So at most 510 hex characters sit between
// the ':' and the CR LF; the decoder also keeps room for the CR while it waits for the LF.
constexpr std::size_t max_hex_chars = 2 * (1 + 253 + 1);
constexpr std::size_t max_pending_chars = max_hex_chars + 1;
// Unit, function code and LRC: anything shorter cannot be a frame.
constexpr std::size_t min_hex_chars = 2 * 3;
// Noise outside frames is reported in runs; a run is cut at this size so a line that never
// sends ':' cannot make the decoder hold an unbounded buffer.
constexpr std::size_t max_noise_run = 513;

constexpr char upper_digits[] = "0123456789ABCDEF";

int hex_value(std::uint8_t c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

void append_hex(Bytes& out, std::uint8_t value) {
    out.push_back(static_cast<std::uint8_t>(upper_digits[value >> 4]));
    out.push_back(static_cast<std::uint8_t>(upper_digits[value & 0x0F]));
}

std::string hex_byte(std::uint8_t value) {
    return {upper_digits[value >> 4], upper_digits[value & 0x0F]};
}

// "'G' (47h)" for printable characters, "0Dh" for the rest: messages must show what arrived.
std::string describe_char(std::uint8_t c) {
    if (c >= 0x20 && c < 0x7F) return std::string("'") + static_cast<char>(c) + "' (" + hex_byte(c) + "h)";
    return hex_byte(c) + "h";
}

// Wire characters of a frame: ':' + body + CR LF.
Bytes wire_frame(const Bytes& body) {
    Bytes raw;
    raw.reserve(body.size() + 3);
    raw.push_back(frame_start);
    raw.insert(raw.end(), body.begin(), body.end());
    raw.push_back(carriage_return);
    raw.push_back(line_feed);
    return raw;
}

// Checks the characters between ':' and CR LF, in the order a reader would: every character
// hex, whole bytes, long enough to hold unit + function + LRC, and finally the LRC itself
// (ramp/soak manual §5.5: two's complement of the sum from ID Number to the end of Data).
FrameEvent decode_body(const Bytes& body) {
    Bytes raw = wire_frame(body);
    for (std::size_t i = 0; i < body.size(); ++i) {
        if (hex_value(body[i]) < 0) {
            return DiscardedBytes{std::move(raw), "non-hex character " + describe_char(body[i]) +
                                                      " at position " + std::to_string(i + 1) +
                                                      " after ':'"};
        }
    }
    if (body.size() % 2 != 0) {
        return DiscardedBytes{std::move(raw), "odd number of hex digits (" + std::to_string(body.size()) +
                                                  "): every byte is two characters"};
    }
    if (body.size() < min_hex_chars) {
        return DiscardedBytes{std::move(raw), "frame too short: " + std::to_string(body.size()) +
                                                  " hex characters, at least 6 needed (unit, "
                                                  "function code, LRC)"};
    }
    Bytes bytes;
    bytes.reserve(body.size() / 2);
    for (std::size_t i = 0; i < body.size(); i += 2) {
        bytes.push_back(static_cast<std::uint8_t>(hex_value(body[i]) * 16 + hex_value(body[i + 1])));
    }
    const std::uint8_t received = bytes.back();
    const std::uint8_t computed = lrc(ByteView(bytes).first(bytes.size() - 1));
    if (received != computed) {
        return DiscardedBytes{std::move(raw), "LRC mismatch: computed " + hex_byte(computed) +
                                                  ", received " + hex_byte(received)};
    }
    Frame frame;
    frame.unit = bytes.front();
    frame.pdu.assign(bytes.begin() + 1, bytes.end() - 1);
    frame.raw = std::move(raw);
    return frame;
}

// Idle CR and LF between frames are line ends, not noise (terminals and some devices send
// extra ones); a run made only of them is dropped silently.
bool only_line_ends(const Bytes& run) {
    return std::all_of(run.begin(), run.end(),
                       [](std::uint8_t c) { return c == carriage_return || c == line_feed; });
}

}  // namespace

std::uint8_t lrc(ByteView bytes) {
    std::uint8_t sum = 0;
    for (std::uint8_t b : bytes) sum = static_cast<std::uint8_t>(sum + b);
    return static_cast<std::uint8_t>(-sum);
}

Bytes ascii_encode(std::uint8_t unit, ByteView pdu) {
    Bytes out;
    out.reserve(2 * pdu.size() + 7);
    out.push_back(frame_start);
    append_hex(out, unit);
    std::uint8_t sum = unit;
    for (std::uint8_t b : pdu) {
        append_hex(out, b);
        sum = static_cast<std::uint8_t>(sum + b);
    }
    append_hex(out, static_cast<std::uint8_t>(-sum));
    out.push_back(carriage_return);
    out.push_back(line_feed);
    return out;
}

AsciiDecoder::AsciiDecoder(unsigned data_bits) : data_bits_(data_bits) {}

void AsciiDecoder::reset() {
    pending_.clear();
    noise_.clear();
    in_frame_ = false;
}

FrameEvents AsciiDecoder::feed(ByteView bytes) {
    FrameEvents events;
    // Helpers that close the current noise run or partial frame and report it.
    const auto report_noise = [&] {
        if (!noise_.empty() && !only_line_ends(noise_)) {
            events.emplace_back(DiscardedBytes{noise_, "characters outside a frame (no ':' before them)"});
        }
        noise_.clear();
    };
    const auto abandon_partial = [&](std::string reason) {
        Bytes raw;
        raw.reserve(pending_.size() + 1);
        raw.push_back(frame_start);
        raw.insert(raw.end(), pending_.begin(), pending_.end());
        events.emplace_back(DiscardedBytes{std::move(raw), std::move(reason)});
        pending_.clear();
        in_frame_ = false;
    };

    for (std::uint8_t c : bytes) {
        // With 7 data bits the eighth bit is whatever the adapter left there (often parity).
        if (data_bits_ < 8) c &= 0x7F;

        if (c == frame_start) {
            // Modbus over serial line V1.02, 2.5.2.1: ':' always starts a new frame.
            if (in_frame_) abandon_partial("new ':' before CR LF: partial frame of " +
                                           std::to_string(pending_.size()) + " characters");
            report_noise();
            in_frame_ = true;
            continue;
        }
        if (!in_frame_) {
            noise_.push_back(c);
            if (noise_.size() >= max_noise_run) report_noise();
            continue;
        }
        if (c == line_feed && !pending_.empty() && pending_.back() == carriage_return) {
            pending_.pop_back();
            events.push_back(decode_body(pending_));
            pending_.clear();
            in_frame_ = false;
            continue;
        }
        pending_.push_back(c);
        if (pending_.size() > max_pending_chars) {
            // Characters up to the CR LF that should have come are then noise.
            abandon_partial("frame too long: more than " + std::to_string(max_hex_chars) +
                            " characters between ':' and CR LF (513-character frame limit)");
        }
    }
    return events;
}

}  // namespace loopwire::codec
