#include "client/dump_file.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/json_checks.hpp"

namespace loopwire::device {
namespace {

Error bad_dump(const std::string& path, const std::string& what) {
    return make_error(ErrorKind::usage, fmt::format("{}: {}; give a file written by `loopwire dump`", path, what));
}

Error wrong_value(const std::string& path, const std::string& pointer, std::string_view expected, const nlohmann::json& found) {
    return bad_dump(path, fmt::format("at {}: expected {}, found {}", pointer, expected, describe_json(found)));
}

// A parameter's "raw": its one word, [150] (or a bare 150), or [] when the dump marks it
// "unread" (the device refused it: nothing to restore). Anything else is refused by name: a
// word that is not an integer 0..65535 would otherwise be skipped and reported as no difference.
Result<std::optional<std::uint16_t>> parameter_word(const std::string& path, const std::string& name,
                                                    const nlohmann::json& entry, const std::string& pointer) {
    if (!entry.is_object()) return wrong_value(path, pointer, fmt::format("parameter {} as an object with \"raw\"", name), entry);
    bool unread = false;
    if (const auto status = entry.find("status"); status != entry.end()) {
        if (!status->is_string()) return wrong_value(path, json_pointer(pointer, "status"), "a status text (\"ok\", \"unread\", ...)", *status);
        unread = status->get<std::string>() == "unread";
    }
    const auto raw = entry.find("raw");
    if (raw == entry.end()) return bad_dump(path, fmt::format("at {}: parameter {} has no \"raw\" words", pointer, name));
    const std::string raw_pointer = json_pointer(pointer, "raw");
    const char* expected = "one raw word, an integer 0..65535 in a list like [150]";
    if (raw->is_array() && raw->empty() && unread) return std::optional<std::uint16_t>{};
    const nlohmann::json* word = &*raw;
    if (raw->is_array()) {
        if (raw->size() != 1) {
            return bad_dump(path, fmt::format("at {}: parameter {}: expected {}, found {} words{}", raw_pointer, name, expected,
                                              raw->size(), raw->empty() ? " (only an \"unread\" parameter has none)" : ""));
        }
        word = &(*raw)[0];
    }
    const auto value = json_word(*word);
    if (!value) return wrong_value(path, raw_pointer, fmt::format("parameter {}: {}", name, expected), *raw);
    return std::optional<std::uint16_t>{*value};
}

Result<void> check_optional_string(const std::string& path, const nlohmann::json& document, const char* key) {
    const auto found = document.find(key);
    if (found == document.end() || found->is_string()) return {};
    return wrong_value(path, json_pointer("", key), "a string", *found);
}

Result<DumpFile> dump_from_document(const std::string& path, const nlohmann::json& document) {
    if (!document.is_object()) return wrong_value(path, "(the document)", "a loopwire dump object", document);
    const auto format = document.find("format");
    if (format == document.end() || !format->is_string() || format->get<std::string>() != "loopwire-dump") {
        return bad_dump(path, fmt::format("is not a loopwire dump (at /format: expected \"loopwire-dump\", found {})",
                                          format == document.end() ? "nothing" : describe_json(*format)));
    }
    const auto version = document.find("version");
    if (version == document.end() || !json_word(*version) || *json_word(*version) != 1) {
        return bad_dump(path, fmt::format("has a dump format version this loopwire does not know (at /version: expected 1, found {})",
                                          version == document.end() ? "nothing" : describe_json(*version)));
    }
    DumpFile dump;
    const auto profile = document.find("profile");
    if (profile == document.end() || !profile->is_string()) {
        return wrong_value(path, "/profile", "the profile id as a string (e.g. \"tc10\")", profile == document.end() ? nlohmann::json() : *profile);
    }
    dump.profile = profile->get<std::string>();
    if (const auto unit = document.find("unit"); unit != document.end()) {
        const auto number = json_word(*unit);
        if (!number || *number > 255) return wrong_value(path, "/unit", "the unit id, an integer 0..255", *unit);
        dump.unit = *number;
    }
    for (const char* key : {"time", "link", "numbering"}) {
        if (auto checked = check_optional_string(path, document, key); !checked) return checked.error();
    }
    dump.time = document.value("time", "");
    const auto parameters = document.find("parameters");
    if (parameters == document.end() || !parameters->is_object()) {
        return wrong_value(path, "/parameters", "an object of parameters by name", parameters == document.end() ? nlohmann::json() : *parameters);
    }
    for (const auto& [name, entry] : parameters->items()) {
        auto word = parameter_word(path, name, entry, json_pointer("/parameters", name));
        if (!word) return word.error();
        if (*word) dump.values.emplace(name, **word);
        if (const auto text = entry.find("text"); entry.is_object() && text != entry.end() && text->is_string()) {
            dump.texts.emplace(name, text->get<std::string>());
        }
    }
    if (const auto identification = document.find("identification"); identification != document.end()) {
        if (!identification->is_object()) return wrong_value(path, "/identification", "an object of raw words by name", *identification);
        for (const auto& [name, entry] : identification->items()) {
            const auto word = json_word(entry);
            if (!word) return wrong_value(path, json_pointer("/identification", name), "a raw word, an integer 0..65535", entry);
            dump.identification.emplace(name, *word);
        }
    }
    return dump;
}

}  // namespace

Result<DumpFile> read_dump_file(const std::string& path) {
    // A pipe is taken (restore /dev/stdin, or a FIFO a script writes into); a directory is said to
    // be one rather than "not valid JSON".
    std::error_code error;
    if (std::filesystem::is_directory(path, error)) return bad_dump(path, "is a directory");
    std::ifstream file(path, std::ios::binary);
    if (!file) return make_error(ErrorKind::usage, fmt::format("cannot read {}: no such file or no permission", path));
    std::ostringstream text;
    text << file.rdbuf();
    return parse_dump_text(text.str(), path);
}

Result<DumpFile> parse_dump_text(const std::string& text, const std::string& path) {
    if (auto deep = json_nesting_problem(text)) return bad_dump(path, *deep);
    const auto document = nlohmann::json::parse(text, nullptr, false);
    if (document.is_discarded()) return bad_dump(path, "is not valid JSON");
    return dump_from_document(path, document);
}

Result<void> check_texts_match_raw(const DumpFile& dump, const Profile& profile, const std::string& path) {
    for (const auto& [name, text] : dump.texts) {
        const Parameter* parameter = profile.find(name);
        const auto raw = dump.values.find(name);
        if (parameter == nullptr || raw == dump.values.end()) continue;
        const auto decoded = decode_value(*parameter, raw->second, dump.values);
        if (!decoded) continue;  // kept raw: nothing to compare with
        const auto formatted = format_value(*parameter, *decoded, dump.values);
        if (!formatted || *formatted == text) continue;
        return bad_dump(path, fmt::format("at {}: its text \"{}\" is not what its raw word {} reads as (\"{}\"): restore "
                                          "writes the raw words, so an edit of text or value would be lost; edit \"raw\", or "
                                          "write the value with `loopwire write` after the restore",
                                          json_pointer("/parameters", name), text, raw->second, *formatted));
    }
    return {};
}

}  // namespace loopwire::device
