#include "session/reply_check.hpp"

#include <fmt/format.h>

#include "session/transaction_text.hpp"

namespace loopwire::session {
namespace {

constexpr std::size_t max_pdu_size = 253;  // Modbus application protocol V1.1b3, 4.1
constexpr std::uint8_t exception_flag = 0x80;

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

ReplyCheck answers_forwarded(Bytes request) {
    return [request = std::move(request)](ByteView reply) -> Result<void> {
        if (reply.empty()) return make_error(ErrorKind::malformed, "the reply has no function code");
        if (reply[0] == request[0]) return {};
        if (reply[0] == (request[0] | exception_flag)) {
            if (reply.size() == 2) return {};
            return make_error(ErrorKind::malformed, fmt::format("an exception reply is 2 bytes, this one is {}", reply.size()));
        }
        return make_error(ErrorKind::mismatch,
                          fmt::format("the reply is for function {}, the request was function {}", reply[0], request[0]));
    };
}

}  // namespace loopwire::session
