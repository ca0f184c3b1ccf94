#pragma once
// Raw words of the AC20: signed 16-bit, decimals dropped (manual Notes 2 and 4).
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace loopwire::device::models {

inline std::uint16_t word_of(double value) {
    return static_cast<std::uint16_t>(static_cast<std::int16_t>(std::lround(std::clamp(value, -32767.0, 32767.0))));
}
inline double signed_word(std::uint16_t raw) { return static_cast<std::int16_t>(raw); }
// Words 124, 125, 129: "Value in Celsius or Fahrenheit as configured at Mbus word 2003".
inline double celsius_to_unit(double celsius, bool fahrenheit) { return fahrenheit ? celsius * 9.0 / 5.0 + 32.0 : celsius; }

}  // namespace loopwire::device::models
