#pragma once
// What answers what: the test a master applies to each whole frame from the unit it asked, for
// typed requests and for PDUs passed through as they are. Shared by the serial and TCP masters.
#include <cstdint>
#include <functional>

#include "codec/pdu.hpp"
#include "common/result.hpp"

namespace loopwire::session {

// Whether a reply PDU answers the request; the error says why not.
using ReplyCheck = std::function<Result<void>(ByteView reply)>;

// A reply that decodes and matches `request` (codec::match_reply), exception replies included.
ReplyCheck answers_request(const codec::Request& request);

// The typed reply from what a master accepted for `request` (an empty PDU after a broadcast);
// an exception reply becomes ErrorKind::exception with its code.
Result<codec::Reply> typed_reply(std::uint8_t unit, const codec::Request& request, Result<Bytes> answered);

// A PDU a master can pass through: a function code 1..127 (0 is not one, 128 and above mark
// exception replies: Modbus application protocol V1.1b3, 6 and 7) and at most 253 bytes (4.1).
Result<void> check_forwardable(ByteView pdu);

// A reply answers a forwarded `request` when it is that function's exception reply (code + 80h,
// one exception code byte: Modbus application protocol V1.1b3, 7), or a normal reply of the same
// function code shaped as the request asks: for reads (FC1/2/3/4/23) a byte count of exactly the
// quantity asked for and a PDU of exactly that length, for FC5/6 the echo of address and value,
// for FC15/16 the echo of address and quantity. Other function codes are checked on the code
// only: their replies' shape cannot be known. A stale reply to another request of the same
// function is refused whenever it differs in shape (docs/DESIGN.md, "what answers what").
ReplyCheck answers_forwarded(ByteView request);

}  // namespace loopwire::session
