#pragma once
// Text that came from a peer (an MQTT payload or topic, an HTTP body, header or target, a
// string from a configuration file) on its way into a log line or a JSON document. Such text
// may be any bytes: invalid UTF-8 (nlohmann's dump() throws type_error 316 on it, which would
// end the process), control characters that rewrite a terminal or split a log line, or
// megabytes that would flood the log. Everything a peer sent goes through these first.
#include <cstddef>
#include <string>
#include <string_view>

namespace loopwire {

// How much of a peer's text a log line shows before it is cut.
constexpr std::size_t peer_text_excerpt = 64;

// `text` in double quotes for a log line: printable ASCII as it is (but `"` and `\`, escaped
// with a backslash), every other byte as \xNN. Longer than `limit` bytes: the first `limit`,
// then "… (N bytes)", so a line stays short whatever was sent.
//   quoted_excerpt("150")           -> "150"
//   quoted_excerpt("\xff")          -> "\xff"
//   quoted_excerpt(200 KB of 'a')   -> "aaaa…aaaa"… (204800 bytes)
std::string quoted_excerpt(std::string_view text, std::size_t limit = peer_text_excerpt);

// The same without the quotes, and with `"` and `\` as they are: for a message of the
// gateway's own that may hold a peer's text ("\"abc\" is not a number").
std::string printable_excerpt(std::string_view text, std::size_t limit = peer_text_excerpt);

// `text` with control bytes (below 0x20, and 0x7f) as \xNN and everything else as it is: for
// a message that quotes a string from a file, which is valid UTF-8 but may hold escapes.
std::string without_control_bytes(std::string_view text);

// The JSON document as text, with invalid UTF-8 replaced by U+FFFD instead of thrown on:
// for every document that holds a peer's (or a device's) text. `Json` is nlohmann::json or
// nlohmann::ordered_json.
template <typename Json>
std::string json_text(const Json& document) {
    return document.dump(-1, ' ', false, Json::error_handler_t::replace);
}

}  // namespace loopwire
