// ASCII stream decoder under arbitrary bytes and read splits. Properties: every frame
// re-encodes to its own characters (case aside), PDUs stay within Modbus limits, every event is
// bounded (hostile input cannot grow buffers) and no event reports bytes that were not fed.
#include <cctype>

#include "codec/ascii.hpp"
#include "fuzz_support.hpp"

using namespace loopwire;
using namespace loopwire::codec;

namespace {

bool same_ignoring_case(const Bytes& a, const Bytes& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i) {
        if (std::toupper(a[i]) != std::toupper(b[i])) return false;
    }
    return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const fuzz::FuzzInput input = fuzz::split_input(data, size);
    AsciiDecoder decoder(input.flag ? 7 : 8);
    fuzz::ReadSplitter reads(input.stream, input.split_seed);
    std::size_t reported = 0;
    while (!reads.done()) {
        for (const FrameEvent& event : decoder.feed(reads.next())) {
            if (const auto* frame = std::get_if<Frame>(&event)) {
                fuzz::check(!frame->pdu.empty() && frame->pdu.size() <= 253, "ASCII PDU is 1..253 bytes");
                fuzz::check(same_ignoring_case(ascii_encode(frame->unit, frame->pdu), frame->raw),
                            "ASCII frame re-encodes to its characters");
                reported += frame->raw.size();
            } else {
                const auto& discarded = std::get<DiscardedBytes>(event);
                fuzz::check(!discarded.bytes.empty() && !discarded.reason.empty(), "ASCII discard has bytes and reason");
                fuzz::check(discarded.bytes.size() <= 513, "ASCII discard bounded by one frame");
                reported += discarded.bytes.size();
            }
        }
        fuzz::check(reported <= input.stream.size(), "ASCII reports no more bytes than were fed");
    }
    return 0;
}
