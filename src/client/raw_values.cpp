#include "client/raw_values.hpp"

#include <array>
#include <bit>
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

struct TypeEntry {
    RawType type;
    std::string_view name;
    unsigned registers;
};

constexpr std::array<TypeEntry, 6> types{{
    {RawType::int16, "int16", 1},
    {RawType::uint16, "uint16", 1},
    {RawType::int32, "int32", 2},
    {RawType::uint32, "uint32", 2},
    {RawType::float32, "float32", 2},
    {RawType::float64, "float64", 4},
}};

const TypeEntry& entry_of(RawType type) {
    for (const auto& entry : types) {
        if (entry.type == type) return entry;
    }
    return types.front();  // unreachable: every enumerator is listed
}

std::uint16_t swapped_bytes(std::uint16_t word) { return static_cast<std::uint16_t>((word << 8) | (word >> 8)); }

// The registers of one value as one unsigned number, most significant register first.
std::uint64_t joined(std::span<const std::uint16_t> registers, const RawLayout& layout) {
    std::uint64_t bits = 0;
    const std::size_t n = registers.size();
    for (std::size_t i = 0; i < n; ++i) {
        std::uint16_t word = registers[layout.word_order == WordOrder::big ? i : n - 1 - i];
        if (layout.byte_swap) word = swapped_bytes(word);
        bits = (bits << 16) | word;
    }
    return bits;
}

// The double nearest to the float's shortest decimal form (see RawNumber).
double float_as_meant(float value) {
    if (!std::isfinite(value)) return static_cast<double>(value);
    const std::string text = fmt::format("{}", value);
    return std::strtod(text.c_str(), nullptr);
}

bool is_digit(char c) { return c >= '0' && c <= '9'; }

constexpr std::size_t most_scale_digits = 15;  // every such integer is exact in a double

}  // namespace

Result<RawType> parse_raw_type(std::string_view text) {
    for (const auto& entry : types) {
        if (entry.name == text) return entry.type;
    }
    return make_error(ErrorKind::usage, fmt::format("unknown type '{}': choose {}", text, raw_type_choices));
}

Result<WordOrder> parse_word_order(std::string_view text) {
    if (text == "big") return WordOrder::big;
    if (text == "little") return WordOrder::little;
    return make_error(ErrorKind::usage, fmt::format("unknown word order '{}': choose big (most significant register first) "
                                                    "or little (least significant first)", text));
}

std::string_view raw_type_name(RawType type) { return entry_of(type).name; }

std::string_view word_order_name(WordOrder order) { return order == WordOrder::big ? "big" : "little"; }

unsigned registers_per_value(RawType type) { return entry_of(type).registers; }

RawNumber decode_value(std::span<const std::uint16_t> registers, const RawLayout& layout) {
    const std::uint64_t bits = joined(registers, layout);
    switch (layout.type) {
        case RawType::int16: return std::int64_t{static_cast<std::int16_t>(bits)};
        case RawType::uint16: return static_cast<std::int64_t>(bits);
        case RawType::int32: return std::int64_t{static_cast<std::int32_t>(bits)};
        case RawType::uint32: return static_cast<std::int64_t>(bits);
        case RawType::float32: return float_as_meant(std::bit_cast<float>(static_cast<std::uint32_t>(bits)));
        case RawType::float64: return std::bit_cast<double>(bits);
    }
    return std::int64_t{0};
}

Result<std::vector<RawNumber>> decode_values(std::span<const std::uint16_t> registers, const RawLayout& layout) {
    const unsigned each = registers_per_value(layout.type);
    if (registers.size() % each != 0) {
        return make_error(ErrorKind::usage, fmt::format("{} registers do not make whole {} values: each takes {}", registers.size(),
                                                        raw_type_name(layout.type), each));
    }
    std::vector<RawNumber> values;
    for (std::size_t at = 0; at < registers.size(); at += each) values.push_back(decode_value(registers.subspan(at, each), layout));
    return values;
}

Result<RawScale> parse_scale(std::string_view text) {
    const auto malformed = [&] {
        return make_error(ErrorKind::usage, fmt::format("--scale '{}' is not a factor: write a decimal number such as 0.1, 10 or -0.5",
                                                        text));
    };
    std::string_view rest = text;
    const bool negative = !rest.empty() && rest.front() == '-';
    if (!rest.empty() && (rest.front() == '-' || rest.front() == '+')) rest.remove_prefix(1);
    const auto point = rest.find('.');
    const std::string_view integer = rest.substr(0, point);
    const std::string_view fraction = point == std::string_view::npos ? std::string_view() : rest.substr(point + 1);
    if (integer.empty() || (point != std::string_view::npos && fraction.empty())) return malformed();
    for (char c : integer) {
        if (!is_digit(c)) return malformed();
    }
    for (char c : fraction) {
        if (!is_digit(c)) return malformed();
    }
    std::string digits = std::string(integer) + std::string(fraction);
    digits.erase(0, std::min(digits.find_first_not_of('0'), digits.size()));
    if (digits.empty()) return make_error(ErrorKind::usage, "--scale 0 would turn every value into 0: give the factor the values are multiplied by");
    if (digits.size() > most_scale_digits || fraction.size() > most_scale_digits) {
        return make_error(ErrorKind::usage, fmt::format("--scale '{}' is too precise: give at most {} significant digits and {} "
                                                        "decimals", text, most_scale_digits, most_scale_digits));
    }
    const auto mantissa = static_cast<std::int64_t>(std::strtoll(digits.c_str(), nullptr, 10));
    return RawScale{negative ? -mantissa : mantissa, static_cast<unsigned>(fraction.size())};
}

double scaled(const RawNumber& value, const RawScale& scale) {
    const double number = std::holds_alternative<std::int64_t>(value) ? static_cast<double>(std::get<std::int64_t>(value))
                                                                     : std::get<double>(value);
    const double product = number * static_cast<double>(scale.mantissa);
    double power = 1.0;  // 10^decimals, exact: decimals is at most 15
    for (unsigned i = 0; i < scale.decimals; ++i) power *= 10.0;
    return product / power;
}

std::string number_text(const RawNumber& value) {
    if (const auto* integer = std::get_if<std::int64_t>(&value)) return fmt::format("{}", *integer);
    const double number = std::get<double>(value);
    if (std::isnan(number)) return "nan";
    if (std::isinf(number)) return number > 0 ? "inf" : "-inf";
    return fmt::format("{}", number);
}

}  // namespace loopwire::device
