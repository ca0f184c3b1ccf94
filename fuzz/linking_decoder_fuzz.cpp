// Linking: the one-frame decoders on the raw input, and the stream decoder under read splits.
// Properties: whatever decodes re-encodes to the same bytes; every streamed frame decodes;
// every byte is in a frame, a discard, or a pending tail shorter than a frame.
#include "codec/linking.hpp"
#include "fuzz_support.hpp"

using namespace loopwire;
using namespace loopwire::codec;

namespace {

void check_single_frame_decoders(ByteView bytes) {
    if (const auto request = decode_linking_request(bytes); request.ok()) {
        fuzz::check(encode_linking_request(*request) == Bytes(bytes.begin(), bytes.end()),
                    "Linking request re-encodes to its bytes");
    }
    if (const auto reply = decode_linking_reply(bytes); reply.ok()) {
        fuzz::check(encode_linking_reply(*reply) == Bytes(bytes.begin(), bytes.end()),
                    "Linking reply re-encodes to its bytes");
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const fuzz::FuzzInput input = fuzz::split_input(data, size);
    check_single_frame_decoders(input.stream);
    if (input.stream.size() >= linking_reply_size) check_single_frame_decoders(input.stream.first(linking_reply_size));
    if (input.stream.size() >= linking_request_size) check_single_frame_decoders(input.stream.first(linking_request_size));

    const bool replies = input.flag;
    const std::size_t frame_size = replies ? linking_reply_size : linking_request_size;
    LinkingDecoder decoder(replies);
    fuzz::ReadSplitter reads(input.stream, input.split_seed);
    std::size_t accounted = 0;
    while (!reads.done()) {
        for (const LinkingEvent& event : decoder.feed(reads.next())) {
            fuzz::check(event.frame.has_value() != event.discarded.has_value(), "Linking event is frame xor discard");
            if (event.frame) {
                fuzz::check(event.frame->size() == frame_size, "Linking frame has the fixed size");
                const bool decodes = replies ? decode_linking_reply(*event.frame).ok()
                                             : decode_linking_request(*event.frame).ok();
                fuzz::check(decodes, "Linking streamed frame decodes");
                accounted += event.frame->size();
            } else {
                fuzz::check(!event.discarded->empty() && !event.reason.empty(), "Linking discard has bytes and reason");
                accounted += event.discarded->size();
            }
        }
    }
    fuzz::check(accounted <= input.stream.size(), "Linking reports no more bytes than were fed");
    fuzz::check(accounted + frame_size > input.stream.size(), "Linking holds back less than one frame");
    return 0;
}
