#include "profile/json_document.hpp"

#include "common/json_checks.hpp"

#include <set>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

using Json = nlohmann::json;

// Walks the SAX events once to learn where each value sits, so a duplicate key can be reported
// with its JSON pointer; the DOM is built by a second, ordinary parse.
class DuplicateKeyFinder final : public nlohmann::json_sax<Json> {
public:
    std::vector<DocumentProblem> duplicates;
    std::string syntax_error;  // nlohmann's message, "parse error at line L, column C: ..."

    bool null() override { return scalar(); }
    bool boolean(bool) override { return scalar(); }
    bool number_integer(number_integer_t) override { return scalar(); }
    bool number_unsigned(number_unsigned_t) override { return scalar(); }
    bool number_float(number_float_t, const string_t&) override { return scalar(); }
    bool string(string_t&) override { return scalar(); }
    bool binary(binary_t&) override { return scalar(); }

    bool start_object(std::size_t) override {
        frames_.push_back(Frame{false, 0, {}, {}});
        return true;
    }
    bool key(string_t& name) override {
        Frame& frame = frames_.back();
        frame.key = name;
        if (!frame.keys.insert(name).second) {
            duplicates.push_back({pointer_of_container(), fmt::format("duplicate key \"{}\"", name)});
        }
        return true;
    }
    bool end_object() override { return end_container(); }
    bool start_array(std::size_t) override {
        frames_.push_back(Frame{true, 0, {}, {}});
        return true;
    }
    bool end_array() override { return end_container(); }

    bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& ex) override {
        syntax_error = ex.what();
        return false;
    }

private:
    struct Frame {
        bool array;
        std::size_t index;       // arrays: the element being read
        std::string key;         // objects: the member being read
        std::set<std::string> keys;
    };
    std::vector<Frame> frames_;

    bool scalar() {
        advance();
        return true;
    }
    bool end_container() {
        frames_.pop_back();
        advance();
        return true;
    }
    void advance() {
        if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
    }
    std::string pointer_of_container() const {
        std::vector<std::string> tokens;
        for (std::size_t i = 0; i + 1 < frames_.size(); ++i) {
            const Frame& frame = frames_[i];
            tokens.push_back(frame.array ? std::to_string(frame.index) : frame.key);
        }
        return json_pointer_text(tokens);
    }
};

// "[json.exception.parse_error.101] parse error at line 3, column 5: syntax error ..." ->
// "line 3, column 5: syntax error ...".
std::string syntax_error_text(const std::string& what) {
    const std::string marker = "parse error at ";
    const auto at = what.find(marker);
    return at == std::string::npos ? what : what.substr(at + marker.size());
}

}  // namespace

std::string json_pointer_text(const std::vector<std::string>& tokens) {
    std::string pointer;
    for (const std::string& token : tokens) {
        pointer += '/';
        for (const char c : token) {
            if (c == '~') pointer += "~0";
            else if (c == '/') pointer += "~1";
            else pointer += c;
        }
    }
    return pointer;
}

const nlohmann::json& object_member(const nlohmann::json& object, const char* key) {
    static const Json empty = Json::object();
    const auto member = object.find(key);
    return member == object.end() ? empty : *member;
}

Error document_error(const std::string& origin, const std::vector<DocumentProblem>& problems) {
    constexpr std::size_t shown = 20;
    std::string message;
    for (std::size_t i = 0; i < problems.size() && i < shown; ++i) {
        if (i > 0) message += '\n';
        const std::string& pointer = problems[i].pointer.empty() ? std::string("/") : problems[i].pointer;
        message += fmt::format("{}: {}: {}", origin, pointer, problems[i].message);
    }
    if (problems.size() > shown) {
        message += fmt::format("\n{}: ... and {} more problems", origin, problems.size() - shown);
    }
    return make_error(ErrorKind::usage, message);
}

Result<nlohmann::json> parse_json_document(std::string_view text, const std::string& origin) {
    if (auto deep = json_nesting_problem(text)) return make_error(ErrorKind::usage, fmt::format("{}: {}", origin, *deep));
    DuplicateKeyFinder finder;
    if (!Json::sax_parse(text, &finder)) {
        return make_error(ErrorKind::usage,
                          fmt::format("{}: {} (not valid JSON)", origin, syntax_error_text(finder.syntax_error)));
    }
    if (!finder.duplicates.empty()) return document_error(origin, finder.duplicates);
    return Json::parse(text);
}

}  // namespace loopwire::device
