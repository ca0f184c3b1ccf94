#pragma once
#include <chrono>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace loopwire {

using Bytes = std::vector<std::uint8_t>;
using ByteView = std::span<const std::uint8_t>;

// Arrival times are points on a monotonic clock; codecs only compare them, never read a clock.
using Instant = std::chrono::steady_clock::time_point;

// "01 03 00 8A" (upper case, space separated): how frames are shown to people.
std::string to_hex(ByteView bytes);

// Accepts "01 03 00 8a", "0103008A", "01:03", "0x01 0x03": pairs of hex digits, optional 0x
// prefixes, separators space, ':', '-', ','. Returns nullopt on anything else (odd digit count,
// non-hex character).
std::optional<Bytes> parse_hex(std::string_view text);
// Why parse_hex refuses `text`, in words: "'019' has an odd number of hex digits, ..." or "'g' is
// not a hex digit"; nothing when it does not.
std::optional<std::string> hex_problem(std::string_view text);

inline std::uint16_t read_be16(ByteView b, std::size_t at) {
    return static_cast<std::uint16_t>((b[at] << 8) | b[at + 1]);
}
inline void append_be16(Bytes& out, std::uint16_t v) {
    out.push_back(static_cast<std::uint8_t>(v >> 8));
    out.push_back(static_cast<std::uint8_t>(v & 0xFF));
}

}  // namespace loopwire
