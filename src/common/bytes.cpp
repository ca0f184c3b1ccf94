#include "common/bytes.hpp"

#include <fmt/format.h>

namespace loopwire {

std::string to_hex(ByteView bytes) {
    static constexpr char digits[] = "0123456789ABCDEF";
    std::string out;
    out.reserve(bytes.size() * 3);
    for (std::size_t i = 0; i < bytes.size(); ++i) {
        if (i != 0) out.push_back(' ');
        out.push_back(digits[bytes[i] >> 4]);
        out.push_back(digits[bytes[i] & 0x0F]);
    }
    return out;
}

namespace {
int hex_value(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}
bool is_separator(char c) { return c == ' ' || c == ':' || c == '-' || c == ',' || c == '\t'; }
}  // namespace

std::optional<Bytes> parse_hex(std::string_view text) {
    Bytes out;
    std::size_t i = 0;
    while (i < text.size()) {
        if (is_separator(text[i])) { ++i; continue; }
        if (text[i] == '0' && i + 1 < text.size() && (text[i + 1] == 'x' || text[i + 1] == 'X')) {
            i += 2;
            continue;
        }
        if (i + 1 >= text.size()) return std::nullopt;
        int hi = hex_value(text[i]);
        int lo = hex_value(text[i + 1]);
        if (hi < 0 || lo < 0) return std::nullopt;
        out.push_back(static_cast<std::uint8_t>(hi * 16 + lo));
        i += 2;
    }
    return out;
}

std::optional<std::string> hex_problem(std::string_view text) {
    std::size_t run = 0;  // hex digits since the last separator
    for (std::size_t i = 0; i <= text.size(); ++i) {
        const char c = i < text.size() ? text[i] : ' ';
        if (hex_value(c) >= 0) {
            ++run;
        } else if ((c == 'x' || c == 'X') && run == 1 && text[i - 1] == '0') {
            run = 0;  // "0x" before a byte
        } else if (is_separator(c)) {
            if (run % 2 == 1) {
                return fmt::format("'{}' has an odd number of hex digits, and each byte takes two (write 9 as 09)",
                                   text.substr(i - run, run));
            }
            run = 0;
        } else {
            return fmt::format("'{}' is not a hex digit", c);
        }
    }
    return std::nullopt;
}

}  // namespace loopwire
