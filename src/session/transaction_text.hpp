#pragma once
// Words for what a master did, shared by the serial and TCP masters' messages.
#include <cstdint>
#include <string>

#include "codec/pdu.hpp"
#include "common/result.hpp"

namespace loopwire::session {

// "read holding registers 100..109 from unit 7"
std::string describe_transaction(std::uint8_t unit, const codec::Request& request);

// "unit 7 answered exception 2 (illegal data address) to read holding registers 100..109"
Error exception_error(std::uint8_t unit, const codec::Request& request, std::uint8_t code);

struct TimeoutContext {
    std::string link;
    long long timeout_ms = 0;
    unsigned tries = 1;
    unsigned discarded_runs = 0;  // garbled frames seen while waiting
};
// No reply: which unit, how long, how many tries, and what to check.
Error timeout_error(std::uint8_t unit, const codec::Request& request, const TimeoutContext& context);

}  // namespace loopwire::session
