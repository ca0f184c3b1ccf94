#include "client/raw_values.hpp"

#include <array>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

struct TypeEntry {
    RawType type;
    std::string_view name;
    unsigned registers;
};

constexpr std::array<TypeEntry, 7> types{{
    {RawType::int16, "int16", 1},
    {RawType::uint16, "uint16", 1},
    {RawType::int32, "int32", 2},
    {RawType::uint32, "uint32", 2},
    {RawType::float32, "float32", 2},
    {RawType::float64, "float64", 4},
    {RawType::string, "string", 1},
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

// Two characters a register, the first in the high byte unless the bytes are swapped; the text
// ends at the first NUL.
std::string registers_text(std::span<const std::uint16_t> registers, bool byte_swap) {
    std::string text;
    for (std::uint16_t word : registers) {
        if (byte_swap) word = swapped_bytes(word);
        for (const auto byte : {static_cast<char>(word >> 8), static_cast<char>(word & 0xFF)}) {
            if (byte == '\0') return text;
            const auto code = static_cast<unsigned char>(byte);
            // Shown, printed and put in JSON as it is only when it is printable ASCII: anything
            // else a device holds there is escaped, so it cannot garble a terminal or a JSON line.
            if (code < 0x20 || code > 0x7E) text += fmt::format("\\x{:02X}", code);
            else text += byte;
        }
    }
    return text;
}

Result<std::vector<std::uint16_t>> text_registers(std::string_view text, bool byte_swap) {
    for (const char c : text) {
        const auto byte = static_cast<unsigned char>(c);
        if (byte < 0x20 || byte > 0x7E) {
            return make_error(ErrorKind::usage, fmt::format("'{}' is not printable ASCII text: a string register holds two ASCII "
                                                            "characters (space to ~); byte 0x{:02X} is not one", text, byte));
        }
    }
    if (text.empty()) return std::vector<std::uint16_t>{0};  // the NUL alone: a string that reads back empty
    std::vector<std::uint16_t> words;
    for (std::size_t i = 0; i < text.size(); i += 2) {
        const auto high = static_cast<unsigned char>(text[i]);
        const auto low = i + 1 < text.size() ? static_cast<unsigned char>(text[i + 1]) : 0u;  // an odd length ends in NUL
        const auto word = static_cast<std::uint16_t>((high << 8) | low);
        words.push_back(byte_swap ? swapped_bytes(word) : word);
    }
    return words;
}

struct ByteOrderEntry {
    std::string_view name;
    WordOrder order;
    bool byte_swap;
};

constexpr std::array<ByteOrderEntry, 4> byte_orders{{
    {"ABCD", WordOrder::big, false},
    {"CDAB", WordOrder::little, false},
    {"BADC", WordOrder::big, true},
    {"DCBA", WordOrder::little, true},
}};

// The registers of a value whose bits are `bits` (most significant first), in the layout's order:
// the inverse of joined().
std::vector<std::uint16_t> split(std::uint64_t bits, const RawLayout& layout) {
    const unsigned n = registers_per_value(layout.type);
    std::vector<std::uint16_t> words(n);
    for (unsigned i = 0; i < n; ++i) {
        auto word = static_cast<std::uint16_t>(bits >> (16 * (n - 1 - i)));
        if (layout.byte_swap) word = swapped_bytes(word);
        words[layout.word_order == WordOrder::big ? i : n - 1 - i] = word;
    }
    return words;
}

bool is_float(RawType type) { return type == RawType::float32 || type == RawType::float64; }

struct IntegerRange {
    std::int64_t lowest;
    std::int64_t highest;
};

IntegerRange range_of(RawType type) {
    switch (type) {
        case RawType::int16: return {std::numeric_limits<std::int16_t>::min(), std::numeric_limits<std::int16_t>::max()};
        case RawType::uint16: return {0, std::numeric_limits<std::uint16_t>::max()};
        case RawType::int32: return {std::numeric_limits<std::int32_t>::min(), std::numeric_limits<std::int32_t>::max()};
        default: return {0, std::numeric_limits<std::uint32_t>::max()};
    }
}

// A whole number as typed: decimal, or hex with 0x (a bit pattern, as a register map gives it).
std::optional<std::int64_t> whole_number(std::string_view text) {
    int radix = 10;
    std::string_view digits = text;
    bool negative = false;
    if (!digits.empty() && digits.front() == '-') {
        negative = true;
        digits.remove_prefix(1);
    } else if (!digits.empty() && digits.front() == '+') {
        digits.remove_prefix(1);
    }
    if (digits.size() > 2 && digits[0] == '0' && (digits[1] == 'x' || digits[1] == 'X')) {
        radix = 16;
        digits.remove_prefix(2);
    }
    std::uint64_t magnitude = 0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), magnitude, radix);
    if (digits.empty() || error != std::errc() || end != digits.data() + digits.size()) return std::nullopt;
    if (magnitude > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) return std::nullopt;
    const auto value = static_cast<std::int64_t>(magnitude);
    return negative ? -value : value;
}

// Any number as typed: 12.5, -3, 1e3, nan, inf. Nothing may follow it.
std::optional<double> any_number(std::string_view text) {
    if (text.empty() || std::isspace(static_cast<unsigned char>(text.front()))) return std::nullopt;
    if (text.find_first_of("xX") != std::string_view::npos) {  // hex is a whole number; strtod would take hex floats
        const auto whole = whole_number(text);
        return whole ? std::optional<double>(static_cast<double>(*whole)) : std::nullopt;
    }
    const std::string copy(text);
    char* end = nullptr;
    const double value = std::strtod(copy.c_str(), &end);
    if (end != copy.c_str() + copy.size()) return std::nullopt;
    return value;
}

double factor_of(const RawScale& scale) { return scaled(std::int64_t{1}, scale); }

// "0..65535", or with a scale the same range in the scaled unit, "0..6553.5 (with --scale 0.1)".
std::string range_text(RawType type, const std::optional<RawScale>& scale) {
    const auto range = range_of(type);
    if (!scale) return fmt::format("{}..{}", range.lowest, range.highest);
    const double low = scaled(range.lowest, *scale);
    const double high = scaled(range.highest, *scale);
    return fmt::format("{}..{} (with --scale {})", std::min(low, high), std::max(low, high), factor_of(*scale));
}

Result<std::uint64_t> integer_bits(std::string_view text, RawType type, const std::optional<RawScale>& scale) {
    const auto name = raw_type_name(type);
    std::int64_t value = 0;
    if (!scale) {
        const auto whole = whole_number(text);
        if (!whole) {
            const bool number = any_number(text).has_value();
            return make_error(ErrorKind::usage, fmt::format("'{}' is not {} {}: give a whole number {}{}", text,
                                                            number ? "a whole number for" : "a number for", name,
                                                            range_text(type, scale),
                                                            number ? " (or --type float32 for a fraction)" : ""));
        }
        value = *whole;
    } else {
        const auto number = any_number(text);
        if (!number || !std::isfinite(*number)) {
            return make_error(ErrorKind::usage, fmt::format("'{}' is not a number: give a number in {}", text, range_text(type, scale)));
        }
        const double units = *number / factor_of(*scale);
        const double nearest = std::round(units);
        if (std::abs(units - nearest) > 1e-9 * std::max(1.0, std::abs(nearest))) {
            return make_error(ErrorKind::usage, fmt::format("{} with --scale {} is {} steps of {}: {} holds whole steps only; "
                                                            "give {} or {}", text, factor_of(*scale), fmt::format("{:.10g}", units),
                                                            factor_of(*scale), name, scaled(static_cast<std::int64_t>(std::floor(units)), *scale),
                                                            scaled(static_cast<std::int64_t>(std::ceil(units)), *scale)));
        }
        if (std::abs(nearest) > 9.0e15) {
            return make_error(ErrorKind::usage, fmt::format("{} does not fit {}: give {}", text, name, range_text(type, scale)));
        }
        value = static_cast<std::int64_t>(nearest);
    }
    const auto range = range_of(type);
    // A hex bit pattern of a signed type (0xFFFF for an int16) is its two's complement.
    const bool pattern = !scale && text.find_first_of("xX") != std::string_view::npos && value >= 0 &&
                         (type == RawType::int16 || type == RawType::int32) && value <= 2 * range.highest + 1;
    if (!pattern && (value < range.lowest || value > range.highest)) {
        return make_error(ErrorKind::usage, fmt::format("{} does not fit {}: give {}", text, name, range_text(type, scale)));
    }
    const unsigned bits = 16 * registers_per_value(type);
    return static_cast<std::uint64_t>(value) & (bits == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1);
}

// The smallest magnitude that rounds to infinity as a float32: the largest float plus half its
// last place (2^128 - 2^103). Below it a number rounds to a finite float, the largest one among
// them: 3.4028235e38, as the largest float32 is printed, is taken.
const double float_overflow = std::ldexp(1.0, 128) - std::ldexp(1.0, 103);

bool names_infinity(std::string_view text) {
    if (!text.empty() && (text.front() == '+' || text.front() == '-')) text.remove_prefix(1);
    std::string lower(text);
    for (auto& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return lower == "inf" || lower == "infinity";
}

std::string largest_of(RawType type) {
    return type == RawType::float64 ? fmt::format("{}", std::numeric_limits<double>::max())
                                    : fmt::format("{}", std::numeric_limits<float>::max());
}

Result<std::uint64_t> float_bits(std::string_view text, RawType type, const std::optional<RawScale>& scale) {
    const auto number = any_number(text);
    if (!number) {
        return make_error(ErrorKind::usage, fmt::format("'{}' is not a number for {}: give a decimal number such as 12.5, "
                                                        "-0.25 or 1e-3 (nan and inf are taken too)", text, raw_type_name(type)));
    }
    const double value = scale ? *number / factor_of(*scale) : *number;
    // Infinity only when asked for by name ("inf", "-infinity"): a number too large for a double
    // (1e999) read as infinity too, and was written as such.
    if (std::isinf(value) && !names_infinity(text)) {
        return make_error(ErrorKind::usage, fmt::format("{} is beyond the largest {}, {}: give a smaller number", text,
                                                        raw_type_name(type), largest_of(type)));
    }
    if (type == RawType::float64) return std::bit_cast<std::uint64_t>(value);
    if (std::isfinite(value) && std::abs(value) >= float_overflow) {
        return make_error(ErrorKind::usage, fmt::format("{} is beyond the largest float32, {}: give a smaller number or --type "
                                                        "float64", text, std::numeric_limits<float>::max()));
    }
    return std::uint64_t{std::bit_cast<std::uint32_t>(static_cast<float>(value))};
}

constexpr std::size_t most_scale_digits = 15;  // every such integer is exact in a double

}  // namespace

Result<RawType> parse_raw_type(std::string_view text) {
    for (const auto& entry : types) {
        if (entry.name == text) return entry.type;
    }
    return make_error(ErrorKind::usage, fmt::format("unknown type '{}': choose {}", text, raw_type_choices));
}

Result<WordOrderChoice> parse_word_order(std::string_view text) {
    if (text == "big") return WordOrderChoice{WordOrder::big, std::nullopt};
    if (text == "little") return WordOrderChoice{WordOrder::little, std::nullopt};
    for (const auto& named : byte_orders) {
        if (named.name == text) return WordOrderChoice{named.order, named.byte_swap};
    }
    return make_error(ErrorKind::usage, fmt::format("unknown word order '{}': choose big (most significant register first) "
                                                    "or little (least significant first), or a byte order: ABCD (big), CDAB "
                                                    "(little), BADC (big, bytes swapped) or DCBA (little, bytes swapped)", text));
}

std::string_view byte_order_name(const RawLayout& layout) {
    for (const auto& named : byte_orders) {
        if (named.order == layout.word_order && named.byte_swap == layout.byte_swap) return named.name;
    }
    return byte_orders.front().name;  // unreachable: the four cover every layout
}

std::string_view raw_type_name(RawType type) { return entry_of(type).name; }

std::string_view word_order_name(WordOrder order) { return order == WordOrder::big ? "big" : "little"; }

unsigned registers_per_value(RawType type) { return entry_of(type).registers; }

RawNumber decode_value(std::span<const std::uint16_t> registers, const RawLayout& layout) {
    if (layout.type == RawType::string) return registers_text(registers, layout.byte_swap);
    const std::uint64_t bits = joined(registers, layout);
    switch (layout.type) {
        case RawType::int16: return std::int64_t{static_cast<std::int16_t>(bits)};
        case RawType::uint16: return static_cast<std::int64_t>(bits);
        case RawType::int32: return std::int64_t{static_cast<std::int32_t>(bits)};
        case RawType::uint32: return static_cast<std::int64_t>(bits);
        case RawType::float32: return float_as_meant(std::bit_cast<float>(static_cast<std::uint32_t>(bits)));
        case RawType::float64: return std::bit_cast<double>(bits);
        case RawType::string: break;
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
    if (std::holds_alternative<std::string>(value)) return 0.0;  // never asked: a string takes no --scale
    const double number = std::holds_alternative<std::int64_t>(value) ? static_cast<double>(std::get<std::int64_t>(value))
                                                                     : std::get<double>(value);
    const double product = number * static_cast<double>(scale.mantissa);
    double power = 1.0;  // 10^decimals, exact: decimals is at most 15
    for (unsigned i = 0; i < scale.decimals; ++i) power *= 10.0;
    return product / power;
}

Result<std::vector<std::uint16_t>> encode_value(std::string_view text, const RawLayout& layout,
                                                const std::optional<RawScale>& scale) {
    if (layout.type == RawType::string) return text_registers(text, layout.byte_swap);
    auto bits = is_float(layout.type) ? float_bits(text, layout.type, scale) : integer_bits(text, layout.type, scale);
    if (!bits) return bits.error();
    return split(*bits, layout);
}

std::string number_text(const RawNumber& value) {
    if (const auto* text = std::get_if<std::string>(&value)) return *text;
    if (const auto* integer = std::get_if<std::int64_t>(&value)) return fmt::format("{}", *integer);
    const double number = std::get<double>(value);
    if (std::isnan(number)) return "nan";
    if (std::isinf(number)) return number > 0 ? "inf" : "-inf";
    return fmt::format("{}", number);
}

}  // namespace loopwire::device
