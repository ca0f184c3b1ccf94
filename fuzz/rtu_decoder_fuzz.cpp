// RTU stream decoder under arbitrary bytes, read splits and gaps. Properties: every frame has a
// matching CRC and is laid out as unit + PDU + CRC; nothing is lost or invented (after the final
// silence every byte fed is in exactly one frame or discard); the buffer stays bounded.
#include <algorithm>
#include <chrono>

#include "codec/rtu.hpp"
#include "fuzz_support.hpp"

using namespace loopwire;
using namespace loopwire::codec;

namespace {

std::size_t account(const FrameEvents& events) {
    std::size_t bytes = 0;
    for (const FrameEvent& event : events) {
        if (const auto* frame = std::get_if<Frame>(&event)) {
            fuzz::check(frame->raw.size() == frame->pdu.size() + 3, "RTU frame is unit + PDU + CRC");
            fuzz::check(frame->raw[0] == frame->unit, "RTU frame unit is its first byte");
            fuzz::check(std::equal(frame->pdu.begin(), frame->pdu.end(), frame->raw.begin() + 1),
                        "RTU frame PDU is the bytes after the unit");
            const std::size_t n = frame->raw.size();
            const auto received = static_cast<std::uint16_t>(frame->raw[n - 2] | (frame->raw[n - 1] << 8));
            fuzz::check(crc16(ByteView(frame->raw).first(n - 2)) == received, "RTU frame CRC matches");
            bytes += n;
        } else {
            const auto& discarded = std::get<DiscardedBytes>(event);
            fuzz::check(!discarded.bytes.empty(), "RTU discard carries bytes");
            fuzz::check(!discarded.reason.empty(), "RTU discard carries a reason");
            bytes += discarded.bytes.size();
        }
    }
    return bytes;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const fuzz::FuzzInput input = fuzz::split_input(data, size);
    const Direction direction = input.flag ? Direction::reply : Direction::request;
    RtuDecoder decoder(direction, CharacterTiming{19200, 11});
    fuzz::ReadSplitter reads(input.stream, input.split_seed);

    Instant now{};
    std::size_t accounted = 0;
    while (!reads.done()) {
        const auto chunk = reads.next();
        // Mostly back-to-back reads, sometimes a gap shorter or longer than 3.5 characters.
        static constexpr std::chrono::microseconds gaps[] = {
            std::chrono::microseconds{0}, std::chrono::microseconds{300}, std::chrono::microseconds{0},
            std::chrono::microseconds{1500}, std::chrono::microseconds{0}, std::chrono::microseconds{5000}};
        now += gaps[reads.step() % 6];
        accounted += account(decoder.feed(chunk, now));
        fuzz::check(decoder.buffered() <= 256 + 64, "RTU buffer stays within a frame plus one read");
        if (reads.step() % 8 == 0) accounted += account(decoder.flush(now + std::chrono::microseconds{500}));
    }
    accounted += account(decoder.flush(now + std::chrono::seconds{1}));
    fuzz::check(decoder.buffered() == 0, "RTU buffer empty after silence");
    fuzz::check(accounted == input.stream.size(), "RTU: every byte is in one frame or one discard");
    return 0;
}
