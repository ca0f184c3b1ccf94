// PDU codec on arbitrary bytes, both directions. Properties: whatever decodes encodes again,
// and decoding that encoding gives the same value (padding bits and other don't-care bits may
// differ, so the comparison is on decoded values); the length a framer would predict from the
// PDU's first bytes equals the PDU's length.
#include "codec/pdu.hpp"
#include "fuzz_support.hpp"

using namespace loopwire;
using namespace loopwire::codec;

namespace {

void check_predicted_length(Direction direction, ByteView pdu) {
    for (std::size_t prefix = 0; prefix <= pdu.size(); ++prefix) {
        const auto length = expected_pdu_length(direction, pdu.first(prefix));
        if (!length) continue;  // more bytes needed
        fuzz::check(*length == pdu.size(), "expected_pdu_length of a valid PDU's prefix is its length");
    }
    fuzz::check(expected_pdu_length(direction, pdu).has_value(), "expected_pdu_length knows a whole valid PDU");
}

void check_request(ByteView pdu) {
    const auto request = decode_request(pdu);
    if (!request.ok()) {
        fuzz::check(!request.error().message.empty(), "request decode error has a message");
        return;
    }
    const auto encoded = encode_request(*request);
    fuzz::check(encoded.ok(), "decoded request encodes");
    const auto again = decode_request(*encoded);
    fuzz::check(again.ok() && *again == *request, "request round trip keeps the value");
    fuzz::check(encoded->size() == pdu.size(), "request round trip keeps the length");
    check_predicted_length(Direction::request, pdu);
}

void check_reply(ByteView pdu) {
    const auto reply = decode_reply(pdu);
    if (!reply.ok()) {
        fuzz::check(!reply.error().message.empty(), "reply decode error has a message");
        return;
    }
    const auto encoded = encode_reply(*reply);
    fuzz::check(encoded.ok(), "decoded reply encodes");
    const auto again = decode_reply(*encoded);
    fuzz::check(again.ok() && *again == *reply, "reply round trip keeps the value");
    fuzz::check(encoded->size() == pdu.size(), "reply round trip keeps the length");
    check_predicted_length(Direction::reply, pdu);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const ByteView pdu(data, size);
    check_request(pdu);
    check_reply(pdu);
    return 0;
}
