#include "session/reply_check.hpp"

#include <algorithm>
#include <array>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "session/transaction_text.hpp"

namespace loopwire::session {
namespace {

constexpr std::size_t max_pdu_size = 253;  // Modbus application protocol V1.1b3, 4.1
constexpr std::uint8_t exception_flag = 0x80;
constexpr std::size_t exception_reply_size = 2;  // function | 80h, exception code (V1.1b3, 7)
// Function, two 16-bit fields: the FC1-6 requests and the FC5/6/15/16 replies (V1.1b3, 6.1-6.6,
// 6.11, 6.12).
constexpr std::size_t two_field_pdu_size = 5;
// FC23 request: function, read address, read quantity, write address, write quantity, byte count
// (V1.1b3, 6.17), then the values.
constexpr std::size_t read_write_header_size = 10;

// The data bytes a read reply must carry for what the request asked; nullopt when the request is
// not a well-formed read (the device answers that with an exception, checked as such).
std::optional<std::size_t> read_reply_data_bytes(ByteView request) {
    const std::uint8_t function = request[0];
    switch (function) {
        case 1:
        case 2:  // V1.1b3 6.1, 6.2: N = quantity / 8, one more byte if the remainder is not 0
            if (request.size() != two_field_pdu_size) return std::nullopt;
            return (std::size_t{read_be16(request, 3)} + 7) / 8;
        case 3:
        case 4:  // V1.1b3 6.3, 6.4: 2 x N bytes for N registers
            if (request.size() != two_field_pdu_size) return std::nullopt;
            return std::size_t{read_be16(request, 3)} * 2;
        case 23:  // V1.1b3 6.17: 2 x N bytes for the N registers read
            if (request.size() < read_write_header_size) return std::nullopt;
            return std::size_t{read_be16(request, 3)} * 2;
        default: return std::nullopt;
    }
}

// A normal reply of the request's function code that is not what the request asked for: a byte
// count other than the quantity read, a length other than that byte count implies, an echo of
// another address, value or quantity. std::nullopt when the shape is right.
std::optional<std::string> shape_problem(ByteView request, ByteView reply) {
    const std::uint8_t function = request[0];
    if (auto data_bytes = read_reply_data_bytes(request)) {
        if (reply.size() < 2) return fmt::format("FC{} reply of {} byte, without a byte count", function, reply.size());
        if (std::size_t{reply[1]} != *data_bytes) {
            return fmt::format("FC{} reply: byte count {}, the request asked for {} bytes", function, reply[1], *data_bytes);
        }
        if (reply.size() != 2 + *data_bytes) {
            return fmt::format("FC{} reply: {} bytes, byte count {} makes {}", function, reply.size(), reply[1], 2 + *data_bytes);
        }
        return std::nullopt;
    }
    switch (function) {
        case 5:
        case 6:  // V1.1b3 6.5, 6.6: the normal response is an echo of the request
        case 15:
        case 16: {  // V1.1b3 6.11, 6.12: function, starting address, quantity written
            if (request.size() < two_field_pdu_size) return std::nullopt;  // malformed: the device says so
            const char* echoed = function <= 6 ? "address and value" : "address and quantity";
            if (reply.size() != two_field_pdu_size) {
                return fmt::format("FC{} reply: {} bytes, the echo of the {} is 5", function, reply.size(), echoed);
            }
            if (!std::equal(reply.begin() + 1, reply.end(), request.begin() + 1, request.begin() + two_field_pdu_size)) {
                return fmt::format("FC{} reply echoes {:04X}h {:04X}h, the request was {:04X}h {:04X}h ({})", function,
                                   read_be16(reply, 1), read_be16(reply, 3), read_be16(request, 1), read_be16(request, 3),
                                   echoed);
            }
            return std::nullopt;
        }
        // Any other function code (diagnostics, file records, FIFO queue, device identification,
        // vendor codes): loopwire cannot know the shape of its reply, so the function code is all
        // that is checked.
        default: return std::nullopt;
    }
}

}  // namespace

ReplyCheck answers_request(const codec::Request& request) {
    return [request](ByteView reply) -> Result<void> {
        auto decoded = codec::decode_reply(reply);
        if (!decoded) return decoded.error();
        auto matched = codec::match_reply(request, std::move(*decoded));
        if (!matched) return matched.error();
        return {};
    };
}

Result<codec::Reply> typed_reply(std::uint8_t unit, const codec::Request& request, Result<Bytes> answered) {
    if (!answered) return answered.error();
    if (unit == 0) return codec::Reply{request.function, codec::ReplyKind::normal, 0, request.address, request.count, {}};
    auto decoded = codec::decode_reply(*answered);
    if (!decoded) return decoded.error();
    auto matched = codec::match_reply(request, std::move(*decoded));
    if (!matched) return matched.error();
    if (matched->kind == codec::ReplyKind::exception) return exception_error(unit, request, matched->exception_code);
    return matched;
}

Result<void> check_forwardable(ByteView pdu) {
    if (pdu.empty()) return make_error(ErrorKind::usage, "an empty PDU cannot be forwarded: it needs a function code");
    if (pdu[0] == 0 || pdu[0] >= exception_flag) {
        return make_error(ErrorKind::usage,
                          fmt::format("function code {} cannot be forwarded: Modbus function codes are 1 to 127", pdu[0]));
    }
    if (pdu.size() > max_pdu_size) {
        return make_error(ErrorKind::usage,
                          fmt::format("a PDU of {} bytes cannot be forwarded: Modbus allows at most {}", pdu.size(), max_pdu_size));
    }
    return {};
}

ReplyCheck answers_forwarded(ByteView whole_request) {
    // Every test reads at most the request's first read_write_header_size bytes and compares its
    // length with no more than that: those bytes, held by value, are all the check needs, and
    // small enough for the std::function to hold without an allocation (one check is made per
    // forwarded request).
    struct Head {
        std::array<std::uint8_t, read_write_header_size> bytes{};
        std::uint8_t size = 0;
        ByteView view() const { return ByteView(bytes.data(), size); }
    };
    Head head;
    head.size = static_cast<std::uint8_t>(std::min(whole_request.size(), head.bytes.size()));
    std::copy_n(whole_request.begin(), head.size, head.bytes.begin());
    return [head](ByteView reply) -> Result<void> {
        const ByteView request = head.view();
        if (request.empty()) return make_error(ErrorKind::usage, "an empty request is answered by nothing");
        if (reply.empty()) return make_error(ErrorKind::malformed, "the reply has no function code");
        if (reply[0] == (request[0] | exception_flag)) {
            if (reply.size() == exception_reply_size) return {};
            return make_error(ErrorKind::malformed, fmt::format("an exception reply is 2 bytes, this one is {}", reply.size()));
        }
        if (reply[0] != request[0]) {
            return make_error(ErrorKind::mismatch,
                              fmt::format("the reply is for function {}, the request was function {}", reply[0], request[0]));
        }
        if (auto problem = shape_problem(request, reply)) return make_error(ErrorKind::mismatch, *problem);
        return {};
    };
}

}  // namespace loopwire::session
