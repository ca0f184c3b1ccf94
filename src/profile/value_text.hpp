#pragma once
// Strict reading of what a user types for a value: no exponents, no rounding, no guessing.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace loopwire::device {

std::string_view trimmed(std::string_view text);
bool equal_ignoring_case(std::string_view a, std::string_view b);

// A decimal number as typed: [+-]digits[.digits]. Trailing zeros of the fraction are dropped
// ("250.50" has one decimal), since they do not change the value.
struct DecimalText {
    bool negative = false;
    std::string integer_digits;   // without leading zeros; "" for 0
    std::string fraction_digits;  // without trailing zeros
};
std::optional<DecimalText> parse_decimal(std::string_view text);

// The number scaled to an integer count of 10^-decimals; nullopt when the text has more
// decimals than that, or is too long to be anything a 16-bit word could hold.
enum class ScaleFailure { too_many_decimals, too_large };
struct Scaled {
    std::optional<std::int64_t> value;
    ScaleFailure failure = ScaleFailure::too_large;
};
Scaled scale_decimal(const DecimalText& number, int decimals);

// "137.0" for 1370 with 1 decimal.
std::string fixed_text(double value, int decimals);

}  // namespace loopwire::device
