#pragma once
// Words for checking a JSON document loopwire reads (dump, simulator state, profile): where a
// value is, as an RFC 6901 JSON pointer ("/units/3/saved/set_point"), and what was found there,
// so an error says exactly which value has the wrong type and what was expected. Readers check
// every type before they get<>() a value: nlohmann's type_error would end the process.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace loopwire {

// `parent` + "/" + key, with '~' and '/' in the key escaped as the RFC asks.
std::string json_pointer(const std::string& parent, std::string_view key);
std::string json_pointer(const std::string& parent, std::size_t index);

// What a value is, for "found ...": `a string "3"`, `the number 1.5`, `an array [150.0]`,
// `an object`, `null`, `true`; long texts are shortened.
std::string describe_json(const nlohmann::json& value);

// How deep arrays and objects nest in the JSON `text` (0 for a scalar), counted on the text itself,
// without recursion (brackets inside strings do not count). Every reader refuses a document nested
// deeper than json_nesting_limit before parsing it: printing a value, as an error message does,
// recurses once per level, and a file of 100 000 brackets overflowed the stack.
std::size_t json_nesting_depth(std::string_view text);
constexpr std::size_t json_nesting_limit = 64;
// "nests arrays and objects 100000 levels deep (at most 64)", when `text` is nested deeper.
std::optional<std::string> json_nesting_problem(std::string_view text);

// The value as a 16-bit word, when it is an integer 0..65535 (not 1.0, not -1, not "1").
std::optional<std::uint16_t> json_word(const nlohmann::json& value);

}  // namespace loopwire
