#include "session/unit_handler.hpp"

namespace loopwire::session {
namespace {

// The wire range a well-formed PDU names (all supported requests start with function, address,
// quantity-or-value).
bool runs_past_last_address(ByteView pdu) {
    if (pdu.size() < 5) return false;
    const std::uint8_t function = pdu[0];
    if (function == 5 || function == 6) return false;
    const unsigned address = read_be16(pdu, 1);
    const unsigned count = read_be16(pdu, 3);
    return count > 0 && address + count > 0x10000;
}

std::uint8_t exception_for_undecodable(ByteView pdu) {
    if (pdu.empty() || !codec::is_supported_function(pdu[0])) {
        return static_cast<std::uint8_t>(codec::ExceptionCode::illegal_function);
    }
    if (runs_past_last_address(pdu)) return static_cast<std::uint8_t>(codec::ExceptionCode::illegal_data_address);
    return static_cast<std::uint8_t>(codec::ExceptionCode::illegal_data_value);
}

// Function code 0 does not exist and 128..255 are the exception replies' codes (application
// protocol V1.1b3, 4.1 and 7): as requests they are unsupported functions, answered with
// exception 1 like any other. Reply cannot carry them (encode_reply refuses function 0 and codes
// with bit 7 set), so the two bytes are built here: the code with bit 7 set, then 01h.
bool is_reserved_function(std::uint8_t function) { return function == 0 || (function & 0x80) != 0; }

}  // namespace

std::optional<Bytes> RequestHandler::handle(ByteView request_pdu, bool) {
    if (request_pdu.empty()) return std::nullopt;
    if (is_reserved_function(request_pdu[0])) {
        return Bytes{static_cast<std::uint8_t>(request_pdu[0] | 0x80),
                     static_cast<std::uint8_t>(codec::ExceptionCode::illegal_function)};
    }
    auto request = codec::decode_request(request_pdu);
    codec::Reply reply = request ? serve(*request)
                                 : codec::exception_reply(request_pdu[0], exception_for_undecodable(request_pdu));
    auto encoded = codec::encode_reply(reply);
    if (!encoded) return std::nullopt;  // a handler bug must not put garbage on the line
    return std::move(*encoded);
}

}  // namespace loopwire::session
