#pragma once
// How a 16-bit word holds a number, shared by decoding and encoding.
#include <cstdint>
#include <optional>

#include "profile/profile.hpp"

namespace loopwire::device {

double power_of_ten(int decimals);

// The raw word read as the profile writes raws: two's complement for int16 words and for enum
// codes when the profile gives negative codes (TC10 Auto -4…), unsigned otherwise.
std::int32_t word_number(const Parameter& parameter, std::uint16_t raw);

// The first special value whose raw matches, compared as int16 and as uint16.
const SpecialValue* special_for(const Parameter& parameter, std::uint16_t raw);
const SpecialValue* special_named(const Parameter& parameter, std::string_view state);

// The label the profile gives this raw, compared as uint16, then as int16 (enum keys are
// written as the manual prints them, signed or not).
const std::string* label_for(const Parameter& parameter, std::uint16_t raw);
std::optional<std::int32_t> key_of_label(const Parameter& parameter, std::string_view label);  // case-insensitive

// Smallest and largest integer the word holds: -32768..32767 for int16 and signed enums,
// 0..65535 otherwise.
std::int64_t word_minimum(const Parameter& parameter);
std::int64_t word_maximum(const Parameter& parameter);

// A number from -32768..65535 as the word that carries it.
std::uint16_t to_word(std::int64_t number);

}  // namespace loopwire::device
