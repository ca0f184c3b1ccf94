// Read Device Identification codec on arbitrary bytes, both directions. Properties: whatever
// decodes encodes again to the same bytes (the format has no don't-care bits), and decoding
// that encoding gives the same value.
#include "codec/device_identification.hpp"
#include "fuzz_support.hpp"

using namespace loopwire;
using namespace loopwire::codec;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const ByteView pdu(data, size);
    if (const auto request = decode_device_identification_request(pdu); request.ok()) {
        const Bytes encoded = encode_device_identification_request(*request);
        fuzz::check(Bytes(pdu.begin(), pdu.end()) == encoded, "a decoded request encodes to its bytes");
    } else {
        fuzz::check(!request.error().message.empty(), "request decode error has a message");
    }
    if (const auto reply = decode_device_identification_reply(pdu); reply.ok()) {
        const auto encoded = encode_device_identification_reply(*reply);
        fuzz::check(encoded.ok(), "a decoded reply encodes");
        fuzz::check(Bytes(pdu.begin(), pdu.end()) == *encoded, "a decoded reply encodes to its bytes");
        const auto again = decode_device_identification_reply(*encoded);
        fuzz::check(again.ok() && *again == *reply, "reply round trip keeps the value");
    } else {
        fuzz::check(!reply.error().message.empty(), "reply decode error has a message");
    }
    return 0;
}
