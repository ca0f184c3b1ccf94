#include "session/transaction_text.hpp"

#include <fmt/format.h>

namespace loopwire::session {
std::string describe_transaction(std::uint8_t unit, const codec::Request& request) {
    const auto last = static_cast<unsigned>(request.address) + (request.count ? request.count - 1 : 0);
    std::string range = request.count > 1 ? fmt::format("{}..{}", request.address, last)
                                          : fmt::format("{}", request.address);
    const bool is_read = request.function <= 4;
    return fmt::format("{} {} {} unit {}", codec::function_name(request.function), range,
                       is_read ? "from" : "to", unit);
}

std::string describe_forwarded(std::uint8_t unit, ByteView pdu) {
    if (pdu.empty()) return fmt::format("an empty PDU to unit {}", unit);
    return fmt::format("function {} ({:02X}h), {} byte{}, to unit {}", pdu[0], pdu[0], pdu.size(),
                       pdu.size() == 1 ? "" : "s", unit);
}

Error exception_error(std::uint8_t unit, const codec::Request& request, std::uint8_t code) {
    return make_error(ErrorKind::exception,
                      fmt::format("unit {} answered exception {} to {}", unit,
                                  codec::describe_exception(code),
                                  describe_transaction(unit, request)),
                      code);
}

Error wrong_reply_error(std::uint8_t unit, const std::string& transaction, const Error& why, ByteView frame) {
    return make_error(why.kind == ErrorKind::mismatch ? ErrorKind::mismatch : ErrorKind::malformed,
                      fmt::format("unit {} answered {} with a reply that is not valid ({}): {}; check that the "
                                  "unit id belongs to the device meant, and that nothing else on the line "
                                  "answers for it",
                                  unit, transaction, why.message, to_hex(frame)));
}

Error timeout_error(std::uint8_t unit, const std::string& transaction, const TimeoutContext& context) {
    std::string message = fmt::format("no reply from unit {} on {} within {} ms ({} {}) to {}", unit,
                                      context.link, context.timeout_ms, context.tries,
                                      context.tries == 1 ? "try" : "tries", transaction);
    if (context.discarded_runs > 0) {
        message += fmt::format(
            "; {} garbled frame(s) arrived instead: the usual cause is a wrong baud rate or "
            "parity (check the device's line settings), or noise on the line",
            context.discarded_runs);
    } else {
        message += "; check the unit id, wiring and line settings, or raise --timeout";
    }
    return make_error(ErrorKind::timeout, std::move(message));
}

}  // namespace loopwire::session
