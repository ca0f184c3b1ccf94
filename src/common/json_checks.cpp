#include "common/json_checks.hpp"

#include <algorithm>

#include <fmt/format.h>

namespace loopwire {

// nlohmann's json_pointer does the escaping; `parent` is always a pointer made here, so it parses.
std::string json_pointer(const std::string& parent, std::string_view key) {
    return (nlohmann::json::json_pointer(parent) / std::string(key)).to_string();
}

std::string json_pointer(const std::string& parent, std::size_t index) {
    return (nlohmann::json::json_pointer(parent) / index).to_string();
}

std::string describe_json(const nlohmann::json& value) {
    // Invalid UTF-8 in a string must not make the description itself throw.
    std::string text = value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    constexpr std::size_t longest = 40;
    if (text.size() > longest) text = text.substr(0, longest) + "...";
    switch (value.type()) {
        case nlohmann::json::value_t::null: return "null";
        case nlohmann::json::value_t::boolean: return text;
        case nlohmann::json::value_t::string: return "a string " + text;
        case nlohmann::json::value_t::number_integer:
        case nlohmann::json::value_t::number_unsigned:
        case nlohmann::json::value_t::number_float: return "the number " + text;
        case nlohmann::json::value_t::array: return "an array " + text;
        case nlohmann::json::value_t::object: return "an object";
        default: return "a value " + text;
    }
}

std::size_t json_nesting_depth(std::string_view text) {
    std::size_t depth = 0;
    std::size_t deepest = 0;
    bool in_string = false;
    bool escaped = false;
    for (const char c : text) {
        if (in_string) {
            if (escaped) {
                escaped = false;
            } else if (c == '\\') {
                escaped = true;
            } else if (c == '"') {
                in_string = false;
            }
            continue;
        }
        if (c == '"') {
            in_string = true;
        } else if (c == '[' || c == '{') {
            deepest = std::max(deepest, ++depth);
        } else if ((c == ']' || c == '}') && depth > 0) {
            --depth;
        }
    }
    return deepest;
}

std::optional<std::string> json_nesting_problem(std::string_view text) {
    const std::size_t depth = json_nesting_depth(text);
    if (depth <= json_nesting_limit) return std::nullopt;
    return fmt::format("nests arrays and objects {} levels deep (at most {})", depth, json_nesting_limit);
}

std::optional<std::uint16_t> json_word(const nlohmann::json& value) {
    if (value.is_number_unsigned()) {
        const auto number = value.get<std::uint64_t>();
        if (number <= 0xFFFF) return static_cast<std::uint16_t>(number);
    } else if (value.is_number_integer()) {
        const auto number = value.get<std::int64_t>();
        if (number >= 0 && number <= 0xFFFF) return static_cast<std::uint16_t>(number);
    }
    return std::nullopt;
}

}  // namespace loopwire
