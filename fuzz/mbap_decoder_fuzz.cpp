// MBAP stream decoder under arbitrary bytes and read splits. Properties: every frame re-encodes
// to its own bytes, PDUs stay within what the length field may announce, the buffer stays below one ADU, and a bad
// header is a malformed error that repeats until reset.
#include "codec/tcp.hpp"
#include "fuzz_support.hpp"

using namespace loopwire;
using namespace loopwire::codec;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const fuzz::FuzzInput input = fuzz::split_input(data, size);
    MbapDecoder decoder;
    fuzz::ReadSplitter reads(input.stream, input.split_seed);
    std::size_t framed = 0;
    while (!reads.done()) {
        auto result = decoder.feed(reads.next());
        if (!result.ok()) {
            fuzz::check(result.error().kind == ErrorKind::malformed, "MBAP error is malformed");
            fuzz::check(!result.error().message.empty(), "MBAP error has a message");
            auto again = decoder.feed(ByteView{});
            fuzz::check(!again.ok() && again.error().message == result.error().message, "MBAP error is sticky");
            decoder.reset();
            fuzz::check(decoder.buffered() == 0, "MBAP reset empties the buffer");
            return 0;
        }
        for (const Frame& frame : result.value()) {
            // Over-long PDUs (length 255..260) are framed by their length for the receiver to refuse.
            fuzz::check(!frame.pdu.empty() && frame.pdu.size() < mbap_max_trusted_length, "MBAP PDU is 1..259 bytes");
            if (frame.pdu.size() <= 253) {
                fuzz::check(mbap_encode(frame.transaction, frame.unit, frame.pdu) == frame.raw,
                            "MBAP frame re-encodes to its bytes");
            }
            framed += frame.raw.size();
        }
        fuzz::check(decoder.buffered() < 6 + mbap_max_trusted_length, "MBAP buffer stays below one ADU");
        if (decoder.broken()) {  // frames came before a bad header: the next feed reports it
            auto again = decoder.feed(ByteView{});
            fuzz::check(!again.ok() && again.error().message == decoder.broken()->message, "MBAP error is sticky");
            return 0;
        }
    }
    fuzz::check(framed + decoder.buffered() == input.stream.size(), "MBAP: every byte framed or pending");
    return 0;
}
