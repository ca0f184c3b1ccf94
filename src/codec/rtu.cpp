// Modbus RTU framing: CRC-16, encoding, character timing and the streaming frame decoder.
// References: Modbus over serial line V1.02, 2.5.1 (RTU framing and timing) and 6.2.2 (CRC);
// AC20 "Error check (CRC-16)", ramp/soak §4.5 and TC10 §3.5 describe the same CRC.
#include "codec/rtu.hpp"

#include <algorithm>
#include <array>
#include <string>
#include <variant>

namespace loopwire::codec {

namespace {

constexpr std::uint16_t crc_polynomial = 0xA001;  // 8005h reflected (AC20 step 4, TC10 §3.5)
constexpr std::uint16_t crc_initial = 0xFFFF;

// One table entry per byte value: the register after shifting that byte through 8 rounds.
constexpr std::array<std::uint16_t, 256> make_crc_table() {
    std::array<std::uint16_t, 256> table{};
    for (std::size_t value = 0; value < table.size(); ++value) {
        auto reg = static_cast<std::uint16_t>(value);
        for (int round = 0; round < 8; ++round) {
            const bool carry = (reg & 1u) != 0;
            reg = static_cast<std::uint16_t>(reg >> 1);
            if (carry) reg ^= crc_polynomial;
        }
        table[value] = reg;
    }
    return table;
}
constexpr auto crc_table = make_crc_table();

constexpr std::size_t unit_size = 1;
constexpr std::size_t crc_size = 2;
// unit + function + CRC: the smallest thing that can be a frame.
constexpr std::size_t min_frame_size = unit_size + 1 + crc_size;
// unit + the largest PDU (253 bytes) + CRC (V1.02 2.5.1).
constexpr std::size_t max_frame_size = unit_size + max_pdu_size + crc_size;

constexpr std::chrono::microseconds fixed_t1_5{750};   // V1.02 2.5.1.1, above 19200 baud
constexpr std::chrono::microseconds fixed_t3_5{1750};
constexpr std::uint32_t fixed_timing_above_baud = 19200;

// How long a silence the reader waits through must last to cut short a frame under way (its
// function code gives its length and fewer bytes have come). On a real line bytes reach the
// reader in batches: a USB adapter holds them up to its latency timer (16 ms by default on FTDI
// chips) and a busy host wakes its reader late, so a pause of a few characters inside a frame is
// the host's, not the wire's, and cutting there turns a good frame into two garbled runs. A frame
// really cut short costs this much longer to be judged; one followed by another frame is judged
// as soon as that frame's bytes come (the CRC tells them apart).
constexpr std::chrono::milliseconds frame_under_way_patience{20};

// ceil(numerator / denominator) microseconds, in integers so no rounding drift creeps in.
std::chrono::microseconds microseconds_rounded_up(std::uint64_t numerator, std::uint64_t denominator) {
    return std::chrono::microseconds{static_cast<std::int64_t>((numerator + denominator - 1) / denominator)};
}

// A baud rate of 0 is a configuration error caught where links are parsed; here it only must
// not divide by zero.
std::uint64_t usable_baud(std::uint32_t baud) { return baud == 0 ? 1 : baud; }

Bytes crc_wire_bytes(std::uint16_t crc) {
    return Bytes{static_cast<std::uint8_t>(crc & 0xFF), static_cast<std::uint8_t>(crc >> 8)};
}

// `candidate` holds at least unit + CRC; its last two bytes are the received CRC, low first.
std::uint16_t received_crc(ByteView candidate) {
    const std::size_t at = candidate.size() - crc_size;
    return static_cast<std::uint16_t>(candidate[at] | (candidate[at + 1] << 8));
}

std::uint16_t computed_crc(ByteView candidate) {
    return crc16(candidate.first(candidate.size() - crc_size));
}

bool crc_matches(ByteView candidate) {
    return candidate.size() >= min_frame_size && computed_crc(candidate) == received_crc(candidate);
}

// The frame length the function code implies (unit + PDU + CRC) for a window that starts at a
// unit byte. nullopt: more bytes needed to tell; 0: the function code gives no length.
std::optional<std::size_t> implied_frame_length(Direction direction, ByteView window) {
    const auto pdu_length = expected_pdu_length(direction, window.subspan(unit_size));
    if (!pdu_length || *pdu_length == 0) return pdu_length;
    return unit_size + *pdu_length + crc_size;
}

bool is_checked_frame(ByteView candidate, std::optional<std::size_t> length) {
    return length && *length != 0 && *length <= max_frame_size && *length <= candidate.size() &&
           crc_matches(candidate.first(*length));
}

// Why bytes were dropped. Put into words only when a discard run starts (the run reports the
// reason of its first byte): resynchronising through noise drops most bytes silently, and
// formatting a message per byte would dominate the decoder's cost.
enum class DropCause {
    crc_mismatch,                  // `bytes` is the candidate frame
    gap_inside_frame,              // `bytes` arrived before silence, fewer than implied_length
    frame_too_long,                // the function code implies more than 256 bytes
    too_few_bytes,                 // fewer than 4 bytes before silence
    no_silence_within_reach,       // unknown function and 256 bytes without a gap
    too_long_before_silence,       // more than 256 bytes of unknown function before silence
    unknown_function_before_frame, // `bytes` precede a frame that checks, too short themselves
};

// What to do with the bytes at the front of the buffer.
struct WaitForMoreBytes {};
struct AcceptFrame {
    std::size_t length;
};
struct DropBytes {
    std::size_t count;
    DropCause cause;
    ByteView bytes;                                // what was judged, for the description
    std::optional<std::size_t> implied_length{};   // frame length the function code implies
};
using Verdict = std::variant<WaitForMoreBytes, AcceptFrame, DropBytes>;

std::string function_of(ByteView bytes) {
    return bytes.size() > unit_size ? std::to_string(bytes[unit_size]) : std::string("?");
}

std::string crc_mismatch_description(ByteView candidate) {
    return "CRC mismatch: computed " + to_hex(crc_wire_bytes(computed_crc(candidate))) +
           ", received " + to_hex(candidate.last(crc_size));
}

std::string describe(const DropBytes& drop) {
    const std::string count = std::to_string(drop.bytes.size());
    const std::string limit = std::to_string(max_frame_size);
    switch (drop.cause) {
        case DropCause::crc_mismatch:
            return crc_mismatch_description(drop.bytes);
        case DropCause::gap_inside_frame:
            return "gap inside frame: silence after " + count +
                   (drop.implied_length ? " of " + std::to_string(*drop.implied_length) : "") + " bytes";
        case DropCause::frame_too_long:
            return "function " + function_of(drop.bytes) + " implies a " +
                   std::to_string(drop.implied_length.value_or(0)) + "-byte frame, more than the " +
                   limit + " an RTU frame can hold";
        case DropCause::too_few_bytes:
            return count + (drop.bytes.size() == 1 ? " byte" : " bytes") +
                   " before silence, too few for a frame (at least 4)";
        case DropCause::no_silence_within_reach:
            return "function " + function_of(drop.bytes) +
                   " has no known length and no silence came within " + limit + " bytes";
        case DropCause::too_long_before_silence:
            return count + " bytes before silence, more than the " + limit + " an RTU frame can hold";
        case DropCause::unknown_function_before_frame:
            return "function " + function_of(drop.bytes) +
                   " unknown and too short before a frame that checks";
    }
    return "discarded";
}

// Judges frame candidates in one snapshot of the decoder's buffer. The snapshot does not change
// during a drain, so what the look-ahead learns about later offsets stays true and its scan
// only moves forward: a drain costs at most one CRC per offset and frame length.
class CandidateJudge {
public:
    CandidateJudge(Direction direction, ByteView buffer) : direction_(direction), buffer_(buffer) {}

    // While bytes keep coming only the length the function code implies can end a frame. A
    // candidate with a bad CRC costs one byte, and the next byte is tried as a unit address:
    // that is how the decoder resynchronises after noise without any timing (pseudo-terminals).
    Verdict while_receiving(std::size_t start, bool resynchronising) {
        const ByteView window = buffer_.subspan(start);
        const auto length = implied_frame_length(direction_, window);
        if (!length) return WaitForMoreBytes{};
        if (*length == 0) return unknown_function_while_receiving(start, resynchronising);
        if (*length > max_frame_size) return DropBytes{1, DropCause::frame_too_long, window, length};
        if (window.size() < *length) return WaitForMoreBytes{};
        const ByteView candidate = window.first(*length);
        if (crc_matches(candidate)) return AcceptFrame{*length};
        return DropBytes{1, DropCause::crc_mismatch, candidate};
    }

    // After more than 3.5 character times of silence every buffered byte gets a verdict now
    // (V1.02 2.5.1.1: the silence marks the end of the frame).
    Verdict after_silence(std::size_t start) {
        const ByteView window = buffer_.subspan(start);
        const auto length = implied_frame_length(direction_, window);
        if (window.size() >= min_frame_size) {
            if (is_checked_frame(window, length)) return AcceptFrame{*length};
            // The silence delimits the frame: everything before it is one candidate. This is
            // how frames with unknown function codes get through, and frames whose length
            // follows the other direction's rules (another slave's reply heard by a slave).
            if (window.size() <= max_frame_size && crc_matches(window)) return AcceptFrame{window.size()};
            if (length == 0u) {
                if (auto next = next_checked_frame(start)) return split_before(start, *next);
            }
        }
        return failed_after_silence(window, length);
    }

private:
    // An unknown function code gives no length, so at a frame boundary only silence can end
    // the frame (or the look-ahead after silence). While resynchronising the byte is more
    // likely noise: a frame that checks further on ends it, so a damaged frame followed at once
    // by a good one costs no wait for silence. Not done at a clean boundary, where it could
    // cut a genuine frame of an unknown function whose data happens to contain a valid frame.
    Verdict unknown_function_while_receiving(std::size_t start, bool resynchronising) {
        if (resynchronising) {
            if (auto next = next_checked_frame(start)) return split_before(start, *next);
        }
        const ByteView window = buffer_.subspan(start);
        // A frame starting here would have ended within 256 bytes; with more and no gap it
        // cannot start here.
        if (window.size() <= max_frame_size) return WaitForMoreBytes{};
        return DropBytes{1, DropCause::no_silence_within_reach, window};
    }

    // The bytes from `start` up to a checked frame at `next`: a frame themselves if their CRC
    // checks, noise otherwise.
    Verdict split_before(std::size_t start, std::size_t next) {
        const ByteView before = buffer_.subspan(start, next - start);
        if (before.size() < min_frame_size) {
            return DropBytes{before.size(), DropCause::unknown_function_before_frame, before};
        }
        if (crc_matches(before)) return AcceptFrame{before.size()};
        return DropBytes{before.size(), DropCause::crc_mismatch, before};
    }

    // The first offset after `start`, within one frame's reach, where a complete frame of known
    // length has a matching CRC.
    std::optional<std::size_t> next_checked_frame(std::size_t start) {
        if (found_ && *found_ > start) return *found_ - start <= max_frame_size ? found_ : std::nullopt;
        found_.reset();
        const std::size_t reach = std::min(buffer_.size(), start + max_frame_size + 1);
        for (std::size_t offset = std::max(scanned_to_, start + 1); offset < reach; ++offset) {
            scanned_to_ = offset + 1;
            const ByteView window = buffer_.subspan(offset);
            if (is_checked_frame(window, implied_frame_length(direction_, window))) {
                found_ = offset;
                return found_;
            }
        }
        return std::nullopt;
    }

    static DropBytes failed_after_silence(ByteView window, std::optional<std::size_t> length) {
        if (length && *length != 0) {
            if (*length > max_frame_size) return DropBytes{1, DropCause::frame_too_long, window, length};
            if (window.size() < *length) return DropBytes{1, DropCause::gap_inside_frame, window, length};
            return DropBytes{1, DropCause::crc_mismatch, window.first(*length)};
        }
        if (window.size() < min_frame_size) return DropBytes{1, DropCause::too_few_bytes, window};
        if (!length) return DropBytes{1, DropCause::gap_inside_frame, window};
        if (window.size() > max_frame_size) return DropBytes{1, DropCause::too_long_before_silence, window};
        return DropBytes{1, DropCause::crc_mismatch, window};
    }

    Direction direction_;
    ByteView buffer_;
    std::size_t scanned_to_ = 0;         // look-ahead: offsets below this have been examined
    std::optional<std::size_t> found_;   // look-ahead: the last checked frame it found
};

Frame make_frame(ByteView wire) {
    Frame frame;
    frame.unit = wire[0];
    const ByteView pdu = wire.subspan(unit_size, wire.size() - unit_size - crc_size);
    frame.pdu.assign(pdu.begin(), pdu.end());
    frame.raw.assign(wire.begin(), wire.end());
    return frame;
}

}  // namespace

std::uint16_t crc16(ByteView bytes) {
    std::uint16_t reg = crc_initial;
    for (std::uint8_t byte : bytes) {
        reg = static_cast<std::uint16_t>((reg >> 8) ^ crc_table[(reg ^ byte) & 0xFF]);
    }
    return reg;
}

Bytes rtu_encode(std::uint8_t unit, ByteView pdu) {
    Bytes frame;
    frame.reserve(unit_size + pdu.size() + crc_size);
    frame.push_back(unit);
    frame.insert(frame.end(), pdu.begin(), pdu.end());
    const Bytes check = crc_wire_bytes(crc16(frame));
    frame.insert(frame.end(), check.begin(), check.end());
    return frame;
}

std::chrono::microseconds CharacterTiming::character_time() const {
    return microseconds_rounded_up(std::uint64_t{bits_per_character} * 1'000'000, usable_baud(baud));
}

std::chrono::microseconds CharacterTiming::t1_5() const {
    if (baud > fixed_timing_above_baud) return fixed_t1_5;
    return microseconds_rounded_up(std::uint64_t{bits_per_character} * 3 * 1'000'000,
                                   2 * usable_baud(baud));
}

std::chrono::microseconds CharacterTiming::t3_5() const {
    if (baud > fixed_timing_above_baud) return fixed_t3_5;
    return microseconds_rounded_up(std::uint64_t{bits_per_character} * 7 * 1'000'000,
                                   2 * usable_baud(baud));
}

RtuDecoder::RtuDecoder(Direction direction, CharacterTiming timing)
    : direction_(direction), timing_(timing) {}

// Only the 3.5-character silence is used. V1.02 2.5.1.1 also calls a frame with a gap of more
// than 1.5 characters inside it incomplete, but operating systems and USB adapters hand bytes
// over in batches with timestamps jittered by more than a character time, so that rule would
// reject good frames; the CRC catches what it would have caught.
// Arrival times are taken when a reader gets the bytes, not when they crossed the wire: a reader
// scheduled late sees a "gap" inside a frame that had none (a loaded machine, a USB adapter
// handing bytes over in batches). So a gap does not end the pending bytes while a frame that
// starts among them (after noise, perhaps) runs on into the new bytes and is either complete
// with a CRC that checks (the CRC is the stronger evidence, as with the 1.5-character rule
// above) or still shorter than its function code says (only more bytes or a silence seen
// while waiting can tell). A silence the reader observes itself (flush) is never second-
// guessed, and frames of unknown length keep ending at any gap: silence is all they have.
bool RtuDecoder::frame_runs_on(ByteView bytes) const {
    Bytes joined(buffer_);
    joined.insert(joined.end(), bytes.begin(), bytes.end());
    for (std::size_t start = 0; start < buffer_.size(); ++start) {
        const ByteView window = ByteView(joined).subspan(start);
        const auto length = implied_frame_length(direction_, window);
        if (!length) return true;  // the function code needs more bytes to tell the length
        if (*length == 0 || *length > max_frame_size || *length <= buffer_.size() - start) continue;
        if (*length > window.size() || crc_matches(window.first(*length))) return true;
    }
    return false;
}

FrameEvents RtuDecoder::feed(ByteView bytes, Instant arrival) {
    if (bytes.empty()) return flush(arrival);
    // A gap before these bytes ends whatever was pending: judge it before appending.
    const bool gap_before = !buffer_.empty() && arrival - last_arrival_ > timing_.t3_5();
    FrameEvents events = !gap_before || frame_runs_on(bytes) ? FrameEvents{} : drain(true);
    buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
    last_arrival_ = arrival;
    FrameEvents more = drain(false);
    events.insert(events.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
    return events;
}

FrameEvents RtuDecoder::flush(Instant now) {
    // From the deadline on (silence_deadline): a reader that waits until then and flushes must
    // get its verdict, not wait again at the same instant.
    if (buffer_.empty() || now - last_arrival_ < silence_needed()) return {};
    return drain(true);
}

// 3.5 characters end a frame (V1.02 2.5.1.1), but a frame under way is given the patience above.
std::chrono::microseconds RtuDecoder::silence_needed() const {
    const auto t3_5 = timing_.t3_5();
    if (!discard_run_.bytes.empty()) return t3_5;  // resynchronising: no frame known to be under way
    const auto length = implied_frame_length(direction_, buffer_);
    // Bytes whose CRC checks as they are form a frame of their own (another direction's, heard
    // on a shared bus: a reply read as a request is a byte short): the silence ends it as usual.
    const bool under_way = length && *length != 0 && *length <= max_frame_size && *length > buffer_.size() &&
                           !crc_matches(buffer_);
    return under_way ? std::max<std::chrono::microseconds>(t3_5, frame_under_way_patience) : t3_5;
}

void RtuDecoder::reset() {
    buffer_.clear();
    discard_run_ = DiscardedBytes{};
}

std::optional<Instant> RtuDecoder::silence_deadline() const {
    if (buffer_.empty()) return std::nullopt;
    return last_arrival_ + silence_needed();
}

FrameEvents RtuDecoder::drain(bool line_quiet) {
    FrameEvents events;
    CandidateJudge judge(direction_, buffer_);
    std::size_t start = 0;  // erased once at the end: sliding byte by byte stays linear
    while (start < buffer_.size()) {
        const bool resynchronising = !discard_run_.bytes.empty();
        const Verdict verdict =
            line_quiet ? judge.after_silence(start) : judge.while_receiving(start, resynchronising);
        if (std::holds_alternative<WaitForMoreBytes>(verdict)) break;
        if (const auto* accept = std::get_if<AcceptFrame>(&verdict)) {
            report_discard_run(events);
            events.emplace_back(make_frame(ByteView(buffer_).subspan(start, accept->length)));
            start += accept->length;
            continue;
        }
        const auto& drop = std::get<DropBytes>(verdict);
        for (std::size_t i = 0; i < drop.count; ++i) {
            if (discard_run_.bytes.empty()) discard_run_.reason = describe(drop);
            extend_discard_run(buffer_[start + i], events);
        }
        start += drop.count;
    }
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start));
    // Nothing left that could continue the run (a quiet drain always empties the buffer).
    if (buffer_.empty()) report_discard_run(events);
    return events;
}

void RtuDecoder::extend_discard_run(std::uint8_t byte, FrameEvents& events) {
    discard_run_.bytes.push_back(byte);
    // Endless noise without a frame or a gap must not grow the run without bound.
    if (discard_run_.bytes.size() >= max_frame_size) report_discard_run(events);
}

void RtuDecoder::report_discard_run(FrameEvents& events) {
    if (discard_run_.bytes.empty()) return;
    events.emplace_back(std::move(discard_run_));
    discard_run_ = DiscardedBytes{};
}

}  // namespace loopwire::codec
