#include "common/peer_text.hpp"

#include <fmt/format.h>

namespace loopwire {

namespace {

std::string escaped(std::string_view text, bool quoted) {
    std::string out;
    out.reserve(text.size() + 16);
    for (const char c : text) {
        const auto byte = static_cast<unsigned char>(c);
        if (quoted && (c == '"' || c == '\\')) {
            out += '\\';
            out += c;
        } else if (byte >= 0x20 && byte < 0x7f) {
            out += c;
        } else {
            out += fmt::format("\\x{:02x}", byte);
        }
    }
    return out;
}

std::string cut_note(std::string_view text, std::size_t limit) {
    return text.size() > limit ? fmt::format("\u2026 ({} bytes)", text.size()) : std::string();
}

}  // namespace

std::string quoted_excerpt(std::string_view text, std::size_t limit) {
    return "\"" + escaped(text.substr(0, limit), true) + "\"" + cut_note(text, limit);
}

std::string printable_excerpt(std::string_view text, std::size_t limit) {
    return escaped(text.substr(0, limit), false) + cut_note(text, limit);
}

std::string without_control_bytes(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    for (const char c : text) {
        const auto byte = static_cast<unsigned char>(c);
        if (byte < 0x20 || byte == 0x7f) {
            out += fmt::format("\\x{:02x}", byte);
        } else {
            out += c;
        }
    }
    return out;
}

}  // namespace loopwire
