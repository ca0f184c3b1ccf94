#pragma once
// Shared by the libFuzzer targets. Input layout for the streaming decoders: the first byte
// configures the run (bit 0: direction or data bits, the rest seeds how the stream is cut into
// reads), every following byte is stream data. Seeds are therefore one byte + a wire frame.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>

namespace loopwire::fuzz {

// A failed property is a crash for libFuzzer: print why, then abort (assert() is compiled out
// in RelWithDebInfo builds).
inline void check(bool condition, const char* what) {
    if (condition) return;
    std::fprintf(stderr, "fuzz property violated: %s\n", what);
    std::abort();
}

struct FuzzInput {
    bool flag = false;            // bit 0 of the first byte
    std::uint32_t split_seed = 0; // the other bits
    std::span<const std::uint8_t> stream;
};

inline FuzzInput split_input(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return {};
    return FuzzInput{(data[0] & 1u) != 0, static_cast<std::uint32_t>(data[0] >> 1) + 1u,
                     std::span<const std::uint8_t>(data + 1, size - 1)};
}

// Cuts a stream into reads of 1..64 bytes, deterministically from the seed, the way a serial
// port or socket hands over bytes: partial frames, several frames at once.
class ReadSplitter {
public:
    ReadSplitter(std::span<const std::uint8_t> stream, std::uint32_t seed) : stream_(stream), state_(seed) {}

    bool done() const { return at_ == stream_.size(); }
    std::span<const std::uint8_t> next() {
        const std::size_t want = 1 + (step() % 64);
        const std::size_t n = want < stream_.size() - at_ ? want : stream_.size() - at_;
        const auto chunk = stream_.subspan(at_, n);
        at_ += n;
        return chunk;
    }
    // A second pseudo-random value per read, for targets that also need timing.
    std::uint32_t step() {
        state_ ^= state_ << 13;
        state_ ^= state_ >> 17;
        state_ ^= state_ << 5;
        return state_;
    }

private:
    std::span<const std::uint8_t> stream_;
    std::size_t at_ = 0;
    std::uint32_t state_;
};

}  // namespace loopwire::fuzz
