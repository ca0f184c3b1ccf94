#include "profile/value_words.hpp"

#include <algorithm>

#include "profile/value_text.hpp"

namespace loopwire::device {
namespace {

bool signed_word(const Parameter& parameter) {
    if (parameter.type == ValueType::int16) return true;
    return !parameter.enum_labels.empty() && parameter.enum_labels.begin()->first < 0;  // keys sorted
}

}  // namespace

double power_of_ten(int decimals) {
    double factor = 1.0;
    for (int i = 0; i < decimals; ++i) factor *= 10.0;
    return factor;
}

std::int32_t word_number(const Parameter& parameter, std::uint16_t raw) {
    return signed_word(parameter) ? static_cast<std::int16_t>(raw) : static_cast<std::int32_t>(raw);
}

const SpecialValue* special_for(const Parameter& parameter, std::uint16_t raw) {
    const auto as_signed = static_cast<std::int16_t>(raw);
    const auto it = std::find_if(parameter.special.begin(), parameter.special.end(),
                                 [&](const SpecialValue& special) { return special.raw == raw || special.raw == as_signed; });
    return it == parameter.special.end() ? nullptr : &*it;
}

const SpecialValue* special_named(const Parameter& parameter, std::string_view state) {
    const auto it = std::find_if(parameter.special.begin(), parameter.special.end(),
                                 [&](const SpecialValue& special) { return equal_ignoring_case(special.state, state); });
    return it == parameter.special.end() ? nullptr : &*it;
}

const std::string* label_for(const Parameter& parameter, std::uint16_t raw) {
    for (const std::int32_t key : {static_cast<std::int32_t>(raw), static_cast<std::int32_t>(static_cast<std::int16_t>(raw))}) {
        if (const auto it = parameter.enum_labels.find(key); it != parameter.enum_labels.end()) return &it->second;
    }
    return nullptr;
}

std::optional<std::int32_t> key_of_label(const Parameter& parameter, std::string_view label) {
    for (const auto& [key, text] : parameter.enum_labels) {
        if (equal_ignoring_case(text, label)) return key;
    }
    return std::nullopt;
}

std::int64_t word_minimum(const Parameter& parameter) { return signed_word(parameter) ? -32768 : 0; }
std::int64_t word_maximum(const Parameter& parameter) { return signed_word(parameter) ? 32767 : 65535; }

std::uint16_t to_word(std::int64_t number) { return static_cast<std::uint16_t>(number & 0xFFFF); }

}  // namespace loopwire::device
