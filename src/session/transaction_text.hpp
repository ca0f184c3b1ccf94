#pragma once
// Words for what a master did, shared by the serial and TCP masters' messages.
#include <cstdint>
#include <string>

#include "codec/pdu.hpp"
#include "common/result.hpp"

namespace loopwire::session {

// "read holding registers 100..109 from unit 7"
std::string describe_transaction(std::uint8_t unit, const codec::Request& request);

// A PDU passed through as it is: "function 43 (2Bh), 5 bytes, to unit 7"
std::string describe_forwarded(std::uint8_t unit, ByteView pdu);

// "unit 7 answered exception 2 (illegal data address) to read holding registers 100..109"
Error exception_error(std::uint8_t unit, const codec::Request& request, std::uint8_t code);

// A whole frame from the unit asked (check bytes right) that does not answer `transaction`:
// which request, why, and the bytes themselves.
Error wrong_reply_error(std::uint8_t unit, const std::string& transaction, const Error& why, ByteView frame);

struct TimeoutContext {
    std::string link;
    long long timeout_ms = 0;
    unsigned tries = 1;
    unsigned discarded_runs = 0;  // garbled frames seen while waiting
};
// No reply: which unit, how long, how many tries, and what to check. `transaction` as
// describe_transaction() or describe_forwarded() words it.
Error timeout_error(std::uint8_t unit, const std::string& transaction, const TimeoutContext& context);

}  // namespace loopwire::session
