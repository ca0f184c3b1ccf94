#include "profile/profile.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/regular_file.hpp"
#include "profile/embedded_profiles.hpp"
#include "profile/json_document.hpp"
#include "profile/profile_checks.hpp"
#include "profile/profile_conversion.hpp"
#include "profile/profile_schema.hpp"

namespace loopwire::device {

const Parameter* Profile::find(std::string_view name) const {
    const auto it = std::find_if(parameters.begin(), parameters.end(),
                                 [&](const Parameter& parameter) { return parameter.name == name; });
    return it == parameters.end() ? nullptr : &*it;
}

Result<Profile> load_profile_text(const std::string& json_text, const std::string& origin) {
    auto document = parse_json_document(json_text, origin);
    if (!document) return document.error();
    // Semantic checks assume the shapes the schema guarantees, so they only run on a document
    // that passed it.
    if (const auto problems = schema_problems(*document); !problems.empty()) return document_error(origin, problems);
    // The conversion get<>()s every value in the types the schema guarantees. Should the schema
    // ever let a wrong type through, that must be an error for the file, not the process ending
    // on an uncaught exception; profile_fuzz looks for such inputs (it fails on this message).
    try {
        if (const auto problems = semantic_problems(*document); !problems.empty()) return document_error(origin, problems);
        return profile_from_document(*document);
    } catch (const std::exception& error) {
        return make_error(ErrorKind::usage, fmt::format("{}: {} ({}); the profile schema should have refused this file: "
                                                        "check the value's type against profile.schema.json",
                                                        origin, profile_type_gap_message, error.what()));
    }
}

// A profile is a few hundred kilobytes at most; anything far larger is the wrong file.
constexpr std::size_t max_profile_file_size = 16 * 1024 * 1024;

Result<Profile> load_profile_file(const std::string& path) {
    // Examined before it is opened: a FIFO or a device given as a profile must be an error, not
    // a wait (common/regular_file.hpp).
    auto text = read_regular_file(path, max_profile_file_size);
    if (!text) {
        return make_error(ErrorKind::usage, fmt::format("{}: cannot open profile ({}); give the path of a "
                                                        "profile JSON file, or a built-in id ({})",
                                                        path, text.error().message, fmt::join(builtin_profile_ids(), ", ")));
    }
    return load_profile_text(*text, path);
}

const std::vector<std::string>& builtin_profile_ids() {
    static const std::vector<std::string> ids = [] {
        std::vector<std::string> list;
        for (const EmbeddedProfileText& embedded : embedded_profile_texts()) list.emplace_back(embedded.id);
        std::sort(list.begin(), list.end());
        return list;
    }();
    return ids;
}

namespace {

using BuiltinProfile = Result<std::shared_ptr<const Profile>>;

// Every built-in profile, loaded and validated on first use; immutable afterwards, so sharing
// it between threads needs no lock (the initialisation itself is thread-safe).
const std::map<std::string, BuiltinProfile, std::less<>>& builtin_profiles() {
    static const auto profiles = [] {
        std::map<std::string, BuiltinProfile, std::less<>> loaded;
        for (const EmbeddedProfileText& embedded : embedded_profile_texts()) {
            auto profile = load_profile_text(std::string(embedded.text), std::string(embedded.origin));
            BuiltinProfile entry = profile ? BuiltinProfile(std::make_shared<const Profile>(std::move(profile).value()))
                                           : BuiltinProfile(profile.error());
            loaded.emplace(std::string(embedded.id), std::move(entry));
        }
        return loaded;
    }();
    return profiles;
}

}  // namespace

Result<std::shared_ptr<const Profile>> builtin_profile(const std::string& id) {
    const auto& profiles = builtin_profiles();
    const auto it = profiles.find(id);
    if (it == profiles.end()) {
        return make_error(ErrorKind::usage, fmt::format("no built-in profile \"{}\"; known profiles: {}", id,
                                                        fmt::join(builtin_profile_ids(), ", ")));
    }
    return it->second;
}

}  // namespace loopwire::device
