#pragma once
// FNV-1a, 64 bits: a fast, stable hash of bytes for what needs no secrecy (an asset's ETag, a
// digest that tells one MQTT command from another). Chained: the hash of one text is the start
// of the next, so several texts hash as one without being joined.
#include <cstdint>
#include <string_view>

namespace loopwire {

inline constexpr std::uint64_t fnv1a_start = 14695981039346656037ull;

constexpr std::uint64_t fnv1a(std::string_view bytes, std::uint64_t hash = fnv1a_start) {
    for (const char c : bytes) {
        hash ^= static_cast<unsigned char>(c);
        hash *= 1099511628211ull;
    }
    return hash;
}

}  // namespace loopwire
