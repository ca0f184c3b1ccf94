#include "profile/value_text.hpp"

#include <algorithm>
#include <cctype>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

bool is_digit(char c) { return c >= '0' && c <= '9'; }

// Anything with more integer digits is far outside -32768..65535 at any scale, and would
// overflow the 64-bit arithmetic below.
constexpr std::size_t longest_integer_part = 12;

}  // namespace

std::string_view trimmed(std::string_view text) {
    const auto is_space = [](char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; };
    while (!text.empty() && is_space(text.front())) text.remove_prefix(1);
    while (!text.empty() && is_space(text.back())) text.remove_suffix(1);
    return text;
}

bool equal_ignoring_case(std::string_view a, std::string_view b) {
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
               return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
           });
}

std::optional<DecimalText> parse_decimal(std::string_view text) {
    DecimalText number;
    if (!text.empty() && (text.front() == '+' || text.front() == '-')) {
        number.negative = text.front() == '-';
        text.remove_prefix(1);
    }
    const auto point = text.find('.');
    const std::string_view integer = text.substr(0, point);
    const std::string_view fraction = point == std::string_view::npos ? std::string_view() : text.substr(point + 1);
    const bool digits_only = std::all_of(integer.begin(), integer.end(), is_digit) &&
                             std::all_of(fraction.begin(), fraction.end(), is_digit);
    if (integer.empty() || !digits_only || (point != std::string_view::npos && fraction.empty())) return std::nullopt;
    number.integer_digits = std::string(integer.substr(std::min(integer.find_first_not_of('0'), integer.size())));
    number.fraction_digits = std::string(fraction.substr(0, fraction.find_last_not_of('0') + 1));
    return number;
}

Scaled scale_decimal(const DecimalText& number, int decimals) {
    if (number.fraction_digits.size() > static_cast<std::size_t>(decimals)) {
        return {std::nullopt, ScaleFailure::too_many_decimals};
    }
    if (number.integer_digits.size() > longest_integer_part) return {std::nullopt, ScaleFailure::too_large};
    std::string digits = number.integer_digits + number.fraction_digits;
    digits.append(static_cast<std::size_t>(decimals) - number.fraction_digits.size(), '0');
    std::int64_t value = 0;
    for (const char digit : digits) value = value * 10 + (digit - '0');
    return {number.negative ? -value : value, ScaleFailure::too_large};
}

std::string fixed_text(double value, int decimals) { return fmt::format("{:.{}f}", value, decimals); }

}  // namespace loopwire::device
