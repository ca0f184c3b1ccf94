#include "codec/linking.hpp"

#include <string>

namespace loopwire::codec {

namespace {

// Ramp/soak manual §6.1: replies start with the header 07h followed by the command 4Dh.
constexpr std::uint8_t reply_header = 0x07;
constexpr std::uint8_t reply_command = 0x4D;

std::string hex_byte(std::uint8_t value) {
    constexpr char digits[] = "0123456789ABCDEF";
    return {digits[value >> 4], digits[value & 0x0F]};
}

bool is_command(std::uint8_t byte) {
    return byte == static_cast<std::uint8_t>(LinkingCommand::read) ||
           byte == static_cast<std::uint8_t>(LinkingCommand::modify_ram) ||
           byte == static_cast<std::uint8_t>(LinkingCommand::write_eeprom);
}

// Command (or reply command 4Dh), ID, address and data: 6 bytes, then the sum.
void append_body(Bytes& out, std::uint8_t command, std::uint8_t id, std::uint16_t address,
                 std::uint16_t data) {
    out.push_back(command);
    out.push_back(id);
    append_be16(out, address);
    append_be16(out, data);
}

// §6.6: the sum runs from Command to the end of Data. In a reply the 07h header is outside it
// (§6.7.1: 07 4D 01 00 8A 03 E8 sums to C3h only without the 07h).
ByteView summed_part(ByteView frame, bool reply) {
    return reply ? frame.subspan(1, 6) : frame.first(6);
}

std::optional<std::string> sum_problem(ByteView frame, bool reply) {
    const std::uint8_t computed = linking_sum(summed_part(frame, reply));
    const std::uint8_t received = frame.back();
    if (computed == received) return std::nullopt;
    return "sum mismatch: computed " + hex_byte(computed) + "h, received " + hex_byte(received) + "h";
}

Error malformed(std::string message) { return make_error(ErrorKind::malformed, std::move(message)); }

// Where a frame can start in the stream. need_more: a reply header 07h with nothing after it.
enum class FrameStart { yes, no, need_more };

FrameStart frame_start(ByteView rest, bool replies) {
    if (!replies) return is_command(rest[0]) ? FrameStart::yes : FrameStart::no;
    if (rest[0] != reply_header) return FrameStart::no;
    if (rest.size() < 2) return FrameStart::need_more;
    return rest[1] == reply_command ? FrameStart::yes : FrameStart::no;
}

// Collects discarded bytes into runs. A run starts at the byte that caused it (a frame whose
// sum failed, or a byte that cannot start a frame) and takes in the bytes skipped after it, so
// each reported run carries exactly one reason.
class DiscardRuns {
public:
    explicit DiscardRuns(std::vector<LinkingEvent>& events) : events_(events) {}

    void skip(std::uint8_t byte, const char* reason_if_new) {
        if (run_.empty()) reason_ = reason_if_new;
        run_.push_back(byte);
    }
    void start(std::uint8_t byte, std::string reason) {
        close();
        reason_ = std::move(reason);
        run_.push_back(byte);
    }
    void close() {
        if (run_.empty()) return;
        events_.push_back(LinkingEvent{std::nullopt, std::move(run_), std::move(reason_)});
        run_.clear();
        reason_.clear();
    }

private:
    std::vector<LinkingEvent>& events_;
    Bytes run_;
    std::string reason_;
};

}  // namespace

std::uint8_t linking_sum(ByteView bytes) {
    std::uint8_t sum = 0;
    for (std::uint8_t b : bytes) sum = static_cast<std::uint8_t>(sum + b);
    return sum;
}

Bytes encode_linking_request(const LinkingRequest& request) {
    Bytes out;
    out.reserve(linking_request_size);
    append_body(out, static_cast<std::uint8_t>(request.command), request.id, request.address, request.data);
    out.push_back(linking_sum(out));
    return out;
}

Bytes encode_linking_reply(const LinkingReply& reply) {
    Bytes out;
    out.reserve(linking_reply_size);
    out.push_back(reply_header);
    append_body(out, reply_command, reply.id, reply.address, reply.data);
    out.push_back(linking_sum(summed_part(out, true)));
    return out;
}

Result<LinkingRequest> decode_linking_request(ByteView frame) {
    if (frame.size() != linking_request_size) {
        return malformed("Linking request size: " + std::to_string(frame.size()) + " bytes, expected 7 "
                         "(command, ID, address, data, sum)");
    }
    if (!is_command(frame[0])) {
        return malformed("Linking request command " + hex_byte(frame[0]) +
                         "h is not R (52h), M (4Dh) or W (57h)");
    }
    if (auto problem = sum_problem(frame, false)) return malformed("Linking request " + *problem);
    return LinkingRequest{static_cast<LinkingCommand>(frame[0]), frame[1], read_be16(frame, 2),
                          read_be16(frame, 4)};
}

Result<LinkingReply> decode_linking_reply(ByteView frame) {
    if (frame.size() != linking_reply_size) {
        return malformed("Linking reply size: " + std::to_string(frame.size()) + " bytes, expected 8 "
                         "(07h, 4Dh, ID, address, data, sum)");
    }
    if (frame[0] != reply_header) {
        return malformed("Linking reply header " + hex_byte(frame[0]) + "h, expected 07h");
    }
    if (frame[1] != reply_command) {
        return malformed("Linking reply command " + hex_byte(frame[1]) + "h, expected 4Dh");
    }
    if (auto problem = sum_problem(frame, true)) return malformed("Linking reply " + *problem);
    return LinkingReply{frame[2], read_be16(frame, 3), read_be16(frame, 5)};
}

LinkingDecoder::LinkingDecoder(bool decode_replies) : replies_(decode_replies) {}

std::vector<LinkingEvent> LinkingDecoder::feed(ByteView bytes) {
    buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
    const std::size_t size = replies_ ? linking_reply_size : linking_request_size;
    const char* noise_reason = replies_ ? "bytes before a Linking reply header (07h 4Dh)"
                                        : "bytes before a Linking command (R 52h, M 4Dh or W 57h)";
    std::vector<LinkingEvent> events;
    DiscardRuns discarded(events);
    std::size_t pos = 0;
    while (pos < buffer_.size()) {
        const ByteView rest = ByteView(buffer_).subspan(pos);
        const FrameStart start = frame_start(rest, replies_);
        if (start == FrameStart::no) {
            discarded.skip(rest[0], noise_reason);
            ++pos;
            continue;
        }
        if (start == FrameStart::need_more || rest.size() < size) break;
        const ByteView candidate = rest.first(size);
        if (auto problem = sum_problem(candidate, replies_)) {
            // The real frame may begin inside this candidate: slide one byte and look again.
            discarded.start(rest[0], *problem + " in " + to_hex(candidate));
            ++pos;
            continue;
        }
        discarded.close();
        events.push_back(LinkingEvent{Bytes(candidate.begin(), candidate.end()), std::nullopt, {}});
        pos += size;
    }
    discarded.close();
    // What is left is the start of a frame still arriving (always shorter than one frame).
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(pos));
    return events;
}

}  // namespace loopwire::codec
