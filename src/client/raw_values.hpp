#pragma once
// Registers of a device loopwire has no profile for, read as the numbers they hold: 16-, 32- and
// 64-bit integers and IEEE 754 floats spread over consecutive registers, in either word order,
// with or without the bytes of each register swapped, optionally scaled; and ASCII text, two
// characters a register. Pure: no I/O.
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "common/result.hpp"

namespace loopwire::device {

enum class RawType { int16, uint16, int32, uint32, float32, float64, string };

// Which register of a 32/64-bit value comes first: big = the most significant (the Modbus
// convention, "ABCD"), little = the least significant ("CDAB").
enum class WordOrder { big, little };

struct RawLayout {
    RawType type = RawType::uint16;
    WordOrder word_order = WordOrder::big;
    bool byte_swap = false;  // the two bytes of every register swapped ("BADC", or "DCBA" with little)
};

inline constexpr std::string_view raw_type_choices = "int16, uint16, int32, uint32, float32, float64 or string";

// "float32" -> RawType::float32; anything else is a usage error listing the choices.
Result<RawType> parse_raw_type(std::string_view text);

// A word order as typed: "big" or "little" say only which register comes first; the byte-order
// names of Modbus tools, where A is the most significant byte, also say whether the bytes of
// each register are swapped: ABCD = big, CDAB = little, BADC = big and swapped, DCBA = little
// and swapped (for a float64, ABCD stands for ABCDEFGH and so on).
struct WordOrderChoice {
    WordOrder order = WordOrder::big;
    std::optional<bool> byte_swap;  // set by the four-letter names only
};
Result<WordOrderChoice> parse_word_order(std::string_view text);
// The four-letter name of a layout: "ABCD", "CDAB", "BADC" or "DCBA".
std::string_view byte_order_name(const RawLayout& layout);
std::string_view raw_type_name(RawType type);
std::string_view word_order_name(WordOrder order);

// Registers one value of the type takes: 1, 2 or 4; 1 for a string, which takes as many as it
// is given (see decode_value).
unsigned registers_per_value(RawType type);

// A decoded value: integer types exactly; floats as doubles. A float32 becomes the double
// nearest to its shortest decimal form (0x3DCCCCCD is 0.1, not 0.10000000149011612), which is
// the number the device meant and what every text and JSON output shows.
// A string is text: ASCII, two characters a register, the first one in each register's high
// byte unless the layout's bytes are swapped (--byte-swap, BADC or DCBA: low byte first, as some
// devices store them). The registers keep the text's order whatever the word order: text has no
// most significant register. The text ends at the first NUL (an odd length is padded with one,
// an empty text is one register of NULs); a byte read that is not printable ASCII is shown as
// \xHH.
using RawNumber = std::variant<std::int64_t, double, std::string>;

// One value from exactly registers_per_value(layout.type) registers, in the order read; for a
// string, all the registers given.
RawNumber decode_value(std::span<const std::uint16_t> registers, const RawLayout& layout);

// Every value of `registers`, in order; a usage error when they do not make whole values
// ("3 registers do not make whole float32 values: each takes 2").
Result<std::vector<RawNumber>> decode_values(std::span<const std::uint16_t> registers, const RawLayout& layout);

// A factor as typed ("0.1", "2", "-0.25"): kept as a decimal so that 1234 * 0.1 is 123.4 to the
// last digit (1234 / 10, one rounding) rather than 123.40000000000001.
struct RawScale {
    std::int64_t mantissa = 1;  // 1234 for 12.34
    unsigned decimals = 0;      // 2 for 12.34
};
// [+-]digits[.digits], not zero, at most 15 significant digits.
Result<RawScale> parse_scale(std::string_view text);
// value * scale, as a double; a string is not scaled (parse_raw_request refuses --scale with it).
double scaled(const RawNumber& value, const RawScale& scale);

// The registers that hold `text` as one value of the layout's type, in the order they are
// written; with `scale`, `text` is the scaled number (what a read with the same --scale shows)
// and the registers hold text / scale. Usage errors say what was wrong: not a number, not a
// whole number for an integer type ("12.34 with --scale 0.1 is 123.4 units of 0.1"), out of
// the type's range (naming the range in the scaled unit). A string takes as many registers as its
// text needs; a character that is not printable ASCII is a usage error.
Result<std::vector<std::uint16_t>> encode_value(std::string_view text, const RawLayout& layout,
                                                const std::optional<RawScale>& scale = std::nullopt);

// The shortest text that reads back as the same number: "-3", "12.5", "0.1", "nan", "inf"; a
// string as it is.
std::string number_text(const RawNumber& value);

}  // namespace loopwire::device
