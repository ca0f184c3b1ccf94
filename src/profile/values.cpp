#include "profile/values.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "profile/value_text.hpp"
#include "profile/value_words.hpp"

namespace loopwire::device {
namespace {

// Decimals beyond 4 are not in any manual; the schema caps fixed decimals there too.
constexpr int most_decimals = 4;

using Value = decltype(EngineeringValue::value);

EngineeringValue with(Value value, std::uint16_t raw, std::string status = "ok") {
    EngineeringValue result;
    result.value = std::move(value);
    result.status = std::move(status);
    result.raw = raw;
    return result;
}

Result<EngineeringValue> decode_bit(const Parameter& parameter, std::uint16_t raw) {
    if (raw > 1) {
        return make_error(ErrorKind::usage, fmt::format("{}: raw {} is not a bit value (0 or 1)", parameter.name, raw));
    }
    if (const std::string* label = label_for(parameter, raw)) return with(*label, raw);
    return with(static_cast<double>(raw), raw);
}

EngineeringValue decode_bits(const Parameter& parameter, std::uint16_t raw) {
    std::map<std::string, bool> bits;
    for (const auto& [bit, name] : parameter.bit_names) bits[name] = ((unsigned{raw} >> bit) & 1U) != 0;
    return with(std::move(bits), raw);
}

EngineeringValue decode_enumeration(const Parameter& parameter, std::uint16_t raw) {
    if (const std::string* label = label_for(parameter, raw)) return with(*label, raw);
    return with(static_cast<double>(word_number(parameter, raw)), raw, unknown_label_status);
}

Result<EngineeringValue> decode_number(const Parameter& parameter, std::uint16_t raw, const RawValues& known) {
    if (const std::string* label = label_for(parameter, raw)) return with(*label, raw);
    const auto decimals = decimals_of(parameter, known);
    if (!decimals) return decimals.error();
    auto decoded = with(word_number(parameter, raw) / power_of_ten(*decimals), raw);
    decoded.decimals = *decimals;
    return decoded;
}

std::string bits_text(const Parameter& parameter, std::uint16_t raw) {
    std::string text;
    for (unsigned bit = 0; bit < 16; ++bit) {
        if (((unsigned{raw} >> bit) & 1U) == 0) continue;
        const auto name = parameter.bit_names.find(bit);
        text += (text.empty() ? "" : "+") + (name == parameter.bit_names.end() ? fmt::format("bit{}", bit) : name->second);
    }
    return text.empty() ? "none" : text;
}

Result<std::uint16_t> raw_of_bits(const Parameter& parameter, const std::map<std::string, bool>& bits,
                                  std::uint16_t unnamed_from) {
    std::uint16_t raw = unnamed_from;
    for (const auto& [bit, name] : parameter.bit_names) {
        raw = static_cast<std::uint16_t>(raw & ~(1U << bit));
        const auto state = bits.find(name);
        if (state == bits.end()) {
            return make_error(ErrorKind::usage, fmt::format("{}: bit \"{}\" has no state", parameter.name, name));
        }
        if (state->second) raw = static_cast<std::uint16_t>(raw | (1U << bit));
    }
    return raw;
}

Result<std::uint16_t> raw_of_number(const Parameter& parameter, double value, const RawValues& known) {
    int decimals = 0;
    if (parameter.type != ValueType::boolean && parameter.type != ValueType::enumeration) {
        const auto found = decimals_of(parameter, known);
        if (!found) return found.error();
        decimals = *found;
    }
    const double scaled = std::round(value * power_of_ten(decimals));
    const std::int64_t top = parameter.type == ValueType::boolean ? 1 : word_maximum(parameter);
    if (!(scaled >= static_cast<double>(word_minimum(parameter)) && scaled <= static_cast<double>(top))) {
        return make_error(ErrorKind::usage, fmt::format("{}: {} does not fit its word", parameter.name, value));
    }
    return to_word(static_cast<std::int64_t>(scaled));
}

Result<EngineeringValue> decode_unitless(const Parameter& parameter, std::uint16_t raw, const RawValues& known);

}  // namespace

Result<int> decimals_of(const Parameter& parameter, const RawValues& known) {
    if (const int* fixed = std::get_if<int>(&parameter.decimals)) return *fixed;
    const std::string& source = std::get<std::string>(parameter.decimals);
    const auto it = known.find(source);
    if (it == known.end()) {
        return make_error(ErrorKind::usage, fmt::format("the decimals of {} come from {}, whose value is not known: "
                                                        "read {} first",
                                                        parameter.name, source, source));
    }
    if (it->second > most_decimals) {
        return make_error(ErrorKind::usage, fmt::format("the decimals of {} come from {}, which reads {} (not 0..{}; "
                                                        "not available in the device's present mode?)",
                                                        parameter.name, source, it->second, most_decimals));
    }
    return static_cast<int>(it->second);
}

std::string unit_of(const Parameter& parameter, const RawValues& known) {
    if (parameter.unit_from.empty()) return parameter.unit;
    for (const UnitRule& rule : parameter.unit_from) {
        const auto word = known.find(rule.parameter);
        if (word == known.end()) continue;
        auto unit = rule.units.find(static_cast<std::int32_t>(word->second));
        if (unit == rule.units.end()) unit = rule.units.find(static_cast<std::int16_t>(word->second));
        if (unit != rule.units.end()) return unit->second;
    }
    return unknown_unit;
}

Result<EngineeringValue> decode_value(const Parameter& parameter, std::uint16_t raw, const RawValues& known) {
    auto decoded = decode_unitless(parameter, raw, known);
    if (decoded) decoded->unit = unit_of(parameter, known);
    return decoded;
}

namespace {

Result<EngineeringValue> decode_unitless(const Parameter& parameter, std::uint16_t raw, const RawValues& known) {
    if (const SpecialValue* special = special_for(parameter, raw)) return with(std::monostate{}, raw, special->state);
    switch (parameter.type) {
        case ValueType::boolean: return decode_bit(parameter, raw);
        case ValueType::bitfield: return decode_bits(parameter, raw);
        case ValueType::enumeration: return decode_enumeration(parameter, raw);
        case ValueType::int16:
        case ValueType::uint16: break;
    }
    return decode_number(parameter, raw, known);
}

}  // namespace

Result<std::uint16_t> raw_of(const Parameter& parameter, const EngineeringValue& value, const RawValues& known) {
    if (std::holds_alternative<std::monostate>(value.value)) {
        const SpecialValue* special = special_named(parameter, value.status);
        if (special == nullptr) {
            return make_error(ErrorKind::usage, fmt::format("{} has no special value \"{}\"", parameter.name, value.status));
        }
        return to_word(special->raw);
    }
    if (const auto* label = std::get_if<std::string>(&value.value)) {
        const auto key = key_of_label(parameter, *label);
        if (!key) return make_error(ErrorKind::usage, fmt::format("{} has no label \"{}\"", parameter.name, *label));
        return to_word(*key);
    }
    if (const auto* bits = std::get_if<std::map<std::string, bool>>(&value.value)) {
        return raw_of_bits(parameter, *bits, value.raw);
    }
    return raw_of_number(parameter, std::get<double>(value.value), known);
}

Result<std::string> format_value(const Parameter& parameter, const EngineeringValue& value, const RawValues& known) {
    if (std::holds_alternative<std::monostate>(value.value)) return value.status;
    if (const auto* label = std::get_if<std::string>(&value.value)) return *label;
    if (std::holds_alternative<std::map<std::string, bool>>(value.value)) return bits_text(parameter, value.raw);
    const double number = std::get<double>(value.value);
    if (parameter.type == ValueType::boolean || parameter.type == ValueType::enumeration) return fixed_text(number, 0);
    const auto decimals = decimals_of(parameter, known);
    if (!decimals) return decimals.error();
    return fixed_text(number, *decimals);
}

std::vector<std::string> dependencies_of(const Parameter& parameter) {
    std::vector<std::string> names;
    const auto add = [&](const std::variant<int, std::string>& decimals_or_name) {
        const auto* name = std::get_if<std::string>(&decimals_or_name);
        if (name != nullptr && std::find(names.begin(), names.end(), *name) == names.end()) names.push_back(*name);
    };
    add(parameter.decimals);
    for (const UnitRule& rule : parameter.unit_from) add(rule.parameter);
    for (const auto& bound : {parameter.min, parameter.max}) {
        const std::string* name = bound ? std::get_if<std::string>(&*bound) : nullptr;
        if (name == nullptr) continue;
        if (const auto source = parameter.bound_sources.find(*name); source != parameter.bound_sources.end()) {
            add(source->second.decimals);  // the bound's decimals before the bound itself
        }
        add(*name);
    }
    return names;
}

}  // namespace loopwire::device
