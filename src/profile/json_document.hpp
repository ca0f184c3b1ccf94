#pragma once
// Strict JSON reading for profiles: syntax errors name line and column, and a key given twice
// in one object is an error (nlohmann::json would silently keep the last one, so a profile with
// two "range" entries would lose one without a word).
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/result.hpp"

namespace loopwire::device {

// One problem found in a profile document: where (a JSON pointer, RFC 6901) and what.
struct DocumentProblem {
    std::string pointer;  // "/parameters/12/access"; "" for the whole document
    std::string message;  // "must be one of r, w, rw (found \"x\")"
};

// "ORIGIN: /pointer: message", one line per problem (at most `shown`, then a count of the rest).
Error document_error(const std::string& origin, const std::vector<DocumentProblem>& problems);

// RFC 6901 pointer from unescaped reference tokens ("~" -> "~0", "/" -> "~1").
std::string json_pointer_text(const std::vector<std::string>& tokens);

// The object member `key`, or an empty object when absent. A reference, unlike json::value(),
// so `for (auto& [k, v] : object_member(x, "enum").items())` iterates no destroyed temporary.
const nlohmann::json& object_member(const nlohmann::json& object, const char* key);

Result<nlohmann::json> parse_json_document(std::string_view text, const std::string& origin);

}  // namespace loopwire::device
