// encode_value: text from a user to the raw word, refusing rather than guessing (values.hpp).
#include <fmt/format.h>

#include "profile/value_text.hpp"
#include "profile/value_words.hpp"
#include "profile/values.hpp"

namespace loopwire::device {
namespace {

Error refused(std::string message) { return make_error(ErrorKind::usage, std::move(message)); }

std::string unit_suffix(const std::string& unit) { return unit.empty() ? std::string() : " " + unit; }

std::string labels_text(const Parameter& parameter) {
    std::string text;
    for (const auto& [key, label] : parameter.enum_labels) text += fmt::format("{}{} = {}", text.empty() ? "" : ", ", key, label);
    return text;
}

std::string bit_names_text(const Parameter& parameter) {
    std::string text;
    for (const auto& [bit, name] : parameter.bit_names) text += fmt::format("{}{} = {}", text.empty() ? "" : ", ", bit, name);
    return text;
}

// What a bound is in engineering units, and how to name it in a message.
struct BoundValue {
    double value = 0;
    std::string text;  // "1200.0 °C" or "set_point_high_limit = 1200.0 °C"
};

class RangeCheck {
public:
    RangeCheck(const Parameter& parameter, const RawValues& known, int decimals)
        : parameter_(parameter), known_(known), decimals_(decimals) {}

    // The bound in engineering units, when it can be resolved from what is known.
    std::optional<double> limit(bool upper) const {
        const auto& bound = upper ? parameter_.max : parameter_.min;
        if (!bound) return std::nullopt;
        const auto resolved = resolve(*bound, upper ? "upper" : "lower");
        return resolved ? std::optional<double>(resolved->value) : std::nullopt;
    }

    Result<void> check(std::string_view typed, double value) const {
        for (const bool upper : {false, true}) {
            const auto& bound = upper ? parameter_.max : parameter_.min;
            if (!bound) continue;
            const auto limit = resolve(*bound, upper ? "upper" : "lower");
            if (!limit) return limit.error();
            // A margin far below the word's resolution, so binary noise in the double cannot
            // refuse a value equal to its limit.
            const double tolerance = 0.5 / power_of_ten(decimals_ + 2);
            const bool outside = upper ? value > limit->value + tolerance : value < limit->value - tolerance;
            if (outside) {
                return refused(fmt::format("{} {} is {} its {} limit {}", parameter_.name, typed,
                                           upper ? "above" : "below", upper ? "upper" : "lower", limit->text));
            }
        }
        return {};
    }

private:
    const Parameter& parameter_;
    const RawValues& known_;
    int decimals_;

    Result<BoundValue> resolve(const Bound& bound, const char* which) const {
        if (const double* fixed = std::get_if<double>(&bound)) {
            if (!parameter_.range_in_counts) {
                return BoundValue{*fixed, fixed_text(*fixed, decimals_) + unit_suffix(parameter_.unit)};
            }
            // A limit printed in display counts: its engineering value at the current decimals,
            // with the count it comes from ("999.9 °C (9999 counts at 1 decimal)").
            const double value = *fixed / power_of_ten(decimals_);
            const std::string unit = unit_of(parameter_, known_);
            return BoundValue{value, fmt::format("{}{} ({} counts at {} decimal{})", fixed_text(value, decimals_),
                                                 unit == unknown_unit ? "" : unit_suffix(unit), fixed_text(*fixed, 0),
                                                 decimals_, decimals_ == 1 ? "" : "s")};
        }
        const std::string& name = std::get<std::string>(bound);
        const auto described = parameter_.bound_sources.find(name);
        if (described == parameter_.bound_sources.end()) {
            return refused(fmt::format("{}: its {} limit {} is not described in bound_sources (load the "
                                       "parameter through its profile)",
                                       parameter_.name, which, name));
        }
        Parameter source;
        source.name = name;
        source.type = described->second.type;
        source.decimals = described->second.decimals;
        source.special = described->second.special;
        source.unit = described->second.unit;
        return resolve_parameter(source, which);
    }

    Result<BoundValue> resolve_parameter(const Parameter& source, const char* which) const {
        const auto raw = known_.find(source.name);
        if (raw == known_.end()) {
            return refused(fmt::format("{}: its {} limit {} is not known; read {} first", parameter_.name, which,
                                       source.name, source.name));
        }
        const auto decoded = decode_value(source, raw->second, known_);
        if (!decoded) return decoded.error();
        const double* number = std::get_if<double>(&decoded->value);
        if (number == nullptr || decoded->status != "ok") {
            return refused(fmt::format("{}: its {} limit {} reads {} (raw {}), not a number to compare with",
                                       parameter_.name, which, source.name, decoded->status, raw->second));
        }
        const auto text = format_value(source, *decoded, known_);
        if (!text) return text.error();
        const std::string& unit = parameter_.unit.empty() ? source.unit : parameter_.unit;
        return BoundValue{*number, fmt::format("{} = {}{}", source.name, *text, unit_suffix(unit))};
    }
};

Result<std::uint16_t> encode_bit(const Parameter& parameter, std::string_view text) {
    for (const char* on : {"1", "on", "true", "yes"}) {
        if (equal_ignoring_case(text, on)) return std::uint16_t{1};
    }
    for (const char* off : {"0", "off", "false", "no"}) {
        if (equal_ignoring_case(text, off)) return std::uint16_t{0};
    }
    return refused(fmt::format("{}: \"{}\" is not a bit value; use 1/0, on/off, true/false{}", parameter.name, text,
                               parameter.enum_labels.empty() ? "" : " or one of " + labels_text(parameter)));
}

std::optional<unsigned> bit_number(const Parameter& parameter, std::string_view name) {
    for (const auto& [bit, bit_name] : parameter.bit_names) {
        if (equal_ignoring_case(bit_name, name)) return bit;
    }
    for (unsigned bit = 0; bit < 16; ++bit) {
        if (equal_ignoring_case(name, fmt::format("bit{}", bit))) return bit;
    }
    return std::nullopt;
}

// A bit field is written as a number (0..65535) or as set bits' names joined by '+'
// ("alarm_1+alarm_3", "bit7", "none"), which is what format_value produces.
Result<std::uint16_t> encode_bits(const Parameter& parameter, std::string_view text) {
    if (const auto number = parse_decimal(text); number && number->fraction_digits.empty()) {
        const auto scaled = scale_decimal(*number, 0);
        if (scaled.value && *scaled.value >= 0 && *scaled.value <= 65535) return to_word(*scaled.value);
        return refused(fmt::format("{}: {} does not fit a 16-bit word (0..65535)", parameter.name, text));
    }
    if (equal_ignoring_case(text, "none")) return std::uint16_t{0};
    std::uint16_t raw = 0;
    while (!text.empty()) {
        const auto plus = text.find('+');
        const std::string_view name = trimmed(text.substr(0, plus));
        const auto bit = bit_number(parameter, name);
        if (!bit) {
            return refused(fmt::format("{}: \"{}\" is not one of its bits ({}; or bitN, or a number)", parameter.name,
                                       name, bit_names_text(parameter)));
        }
        raw = static_cast<std::uint16_t>(raw | (1U << *bit));
        text = plus == std::string_view::npos ? std::string_view() : text.substr(plus + 1);
    }
    return raw;
}

// A bit field's range (TC10 o1AL 0…63) limits the word as a number.
Result<std::uint16_t> encode_bit_field(const Parameter& parameter, std::string_view text,
                                       const RawValues& known) {
    const auto raw = encode_bits(parameter, text);
    if (!raw) return raw;
    if (const auto in_range = RangeCheck(parameter, known, 0).check(text, *raw); !in_range) {
        return in_range.error();
    }
    return raw;
}

Result<std::uint16_t> encode_enumeration(const Parameter& parameter, std::string_view text) {
    const auto number = parse_decimal(text);
    if (number && number->fraction_digits.empty()) {
        const auto scaled = scale_decimal(*number, 0);
        if (scaled.value && parameter.enum_labels.contains(static_cast<std::int32_t>(*scaled.value))) {
            return to_word(*scaled.value);
        }
    }
    return refused(fmt::format("{}: \"{}\" is not one of its values: {}", parameter.name, text, labels_text(parameter)));
}

Result<std::uint16_t> encode_number(const Parameter& parameter, std::string_view text,
                                    const RawValues& known) {
    const auto number = parse_decimal(text);
    if (!number) {
        return refused(fmt::format("{}: \"{}\" is not a number (write it like 250, -12.5){}", parameter.name, text,
                                   parameter.enum_labels.empty() ? "" : " or one of " + labels_text(parameter)));
    }
    const auto decimals = decimals_of(parameter, known);
    if (!decimals) return decimals.error();
    const auto scaled = scale_decimal(*number, *decimals);
    if (!scaled.value && scaled.failure == ScaleFailure::too_many_decimals) {
        return refused(fmt::format("{} {} has {} decimals, but {} takes {} (values are not rounded)", parameter.name,
                                   text, number->fraction_digits.size(), parameter.name, *decimals));
    }
    const double value = scaled.value ? static_cast<double>(*scaled.value) / power_of_ten(*decimals) : 0.0;
    if (scaled.value) {
        if (const auto in_range = RangeCheck(parameter, known, *decimals).check(text, value); !in_range) {
            return in_range.error();
        }
    }
    const std::int64_t lowest = word_minimum(parameter);
    const std::int64_t highest = word_maximum(parameter);
    if (!scaled.value || *scaled.value < lowest || *scaled.value > highest) {
        // The limits are those of a 16-bit word, exact as doubles.
        return refused(fmt::format("{} {} does not fit its 16-bit word: with {} decimals it holds {} .. {}",
                                   parameter.name, text, *decimals,
                                   fixed_text(static_cast<double>(lowest) / power_of_ten(*decimals), *decimals),
                                   fixed_text(static_cast<double>(highest) / power_of_ten(*decimals), *decimals)));
    }
    return to_word(*scaled.value);
}

Result<std::uint16_t> encode(const Parameter& parameter, std::string_view typed,
                             const RawValues& known) {
    if (!parameter.writable) return refused(fmt::format("{} is read-only", parameter.name));
    const std::string_view text = trimmed(typed);
    if (text.empty()) return refused(fmt::format("{}: no value given", parameter.name));
    // Labels and special states are legal by definition: they skip the range check (AC20
    // 7FFFh 'step' lies above any set point limit; TC10 'off' is 0 below a 1..9999 range).
    if (const auto key = key_of_label(parameter, text)) return to_word(*key);
    if (const SpecialValue* special = special_named(parameter, text)) return to_word(special->raw);
    switch (parameter.type) {
        case ValueType::boolean: return encode_bit(parameter, text);
        case ValueType::bitfield: return encode_bit_field(parameter, text, known);
        case ValueType::enumeration: return encode_enumeration(parameter, text);
        case ValueType::int16:
        case ValueType::uint16: break;
    }
    return encode_number(parameter, text, known);
}

}  // namespace

Result<std::uint16_t> encode_value(const Parameter& parameter, std::string_view text, const RawValues& known) {
    return encode(parameter, text, known);
}

ValueLimits limits_of(const Parameter& parameter, const RawValues& known) {
    // An enumeration's range is the codes it takes (TC10 control_state 0..2): what a code
    // written as a number is checked against, shown as it is by every front.
    if (parameter.type == ValueType::enumeration) {
        const auto fixed = [](const std::optional<Bound>& bound) {
            const double* number = bound ? std::get_if<double>(&*bound) : nullptr;
            return number ? std::optional<double>(*number) : std::nullopt;
        };
        return {fixed(parameter.min), fixed(parameter.max)};
    }
    if (parameter.type != ValueType::int16 && parameter.type != ValueType::uint16) return {};
    const auto decimals = decimals_of(parameter, known);
    // Without its decimals a bound in display counts cannot be scaled; a named or plain one can.
    if (!decimals && parameter.range_in_counts) return {};
    const RangeCheck range(parameter, known, decimals ? *decimals : 0);
    return {range.limit(false), range.limit(true)};
}

bool raw_in_range(const Parameter& parameter, std::uint16_t raw, const RawValues& known) {
    const auto decoded = decode_value(parameter, raw, known);
    if (!decoded || decoded->status == unknown_label_status) return false;
    if (decoded->status != "ok") return true;
    const auto text = format_value(parameter, *decoded, known);
    if (!text) return false;
    if (parameter.writable) return encode_value(parameter, *text, known).ok();
    // The access check is not this function's business: judge a read-only word as if writable.
    Parameter writable = parameter;
    writable.writable = true;
    return encode_value(writable, *text, known).ok();
}

}  // namespace loopwire::device
