#include "profile/profile_registry.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "common/json_checks.hpp"

namespace loopwire::device {
namespace {

namespace fs = std::filesystem;

std::string describe_origin(const std::string& origin) {
    return origin == builtin_origin ? "the built-in profile" : origin;
}

// The id an unusable file was probably meant to define, so that asking for that id can point
// at the file: its "id" member when the JSON gets that far, else its name without ".json".
std::string likely_profile_id(const fs::path& path) {
    std::ifstream file(path, std::ios::binary);
    if (file) {
        std::ostringstream text;
        text << file.rdbuf();
        const auto document = json_nesting_problem(text.str())
                                  ? nlohmann::json()
                                  : nlohmann::json::parse(text.str(), nullptr, /*allow_exceptions=*/false);
        if (document.is_object()) {
            const auto id = document.find("id");
            if (id != document.end() && id->is_string()) return id->get<std::string>();
        }
    }
    return path.stem().string();
}

// The *.json files directly in `folder`, sorted so that messages come in a stable order; an
// absent folder is simply none (most users have no profiles of their own).
std::vector<fs::path> folder_profile_files(const std::string& folder, std::vector<std::string>& warnings) {
    std::vector<fs::path> files;
    std::error_code error;
    fs::directory_iterator entries(folder, error);
    if (error) {
        if (error != std::errc::no_such_file_or_directory) {
            warnings.push_back(fmt::format("cannot read the profile folder {} ({}); its profiles are not loaded: "
                                           "check its permissions",
                                           folder, error.message()));
        }
        return files;
    }
    // Stepped with an error code: a folder that fails half-way is a warning, not an exception.
    for (; entries != fs::directory_iterator(); entries.increment(error)) {
        const fs::directory_entry& entry = *entries;
        if (entry.path().extension() != ".json") continue;
        std::error_code type_error;
        if (!entry.is_regular_file(type_error)) {
            warnings.push_back(fmt::format("{}: not a regular file; skipped", entry.path().string()));
            continue;
        }
        files.push_back(entry.path());
    }
    if (error) {
        warnings.push_back(fmt::format("reading the profile folder {} failed ({}); some of its profiles may not be loaded",
                                       folder, error.message()));
    }
    std::sort(files.begin(), files.end());
    return files;
}

Result<RegisteredProfile> load_registered(const std::string& path) {
    auto profile = load_profile_file(path);
    if (!profile) return profile.error();
    return RegisteredProfile{std::make_shared<const Profile>(std::move(profile).value()), path};
}

}  // namespace

std::optional<std::string> user_profile_folder(const char* xdg_config_home, const char* home) {
    if (xdg_config_home != nullptr && *xdg_config_home != '\0') {
        return (fs::path(xdg_config_home) / "loopwire" / "profiles").string();
    }
    if (home != nullptr && *home != '\0') return (fs::path(home) / ".config" / "loopwire" / "profiles").string();
    return std::nullopt;
}

Result<ProfileRegistry> ProfileRegistry::builtins() {
    ProfileRegistry registry;
    for (const std::string& id : builtin_profile_ids()) {
        auto profile = builtin_profile(id);
        if (!profile) return profile.error();
        if (auto added = registry.add({*profile, std::string(builtin_origin)}); !added) return added.error();
    }
    return registry;
}

namespace {

// Whether `path` is a file already loaded (the same file named twice, or given with --profile and
// found again in the profile folder): loaded once, not "defined twice".
bool loaded_already(std::vector<fs::path>& loaded, const fs::path& path) {
    std::error_code error;
    for (const fs::path& before : loaded) {
        if (fs::equivalent(before, path, error)) return true;
    }
    loaded.push_back(path);
    return false;
}

}  // namespace

Result<ProfileRegistry> ProfileRegistry::build(const ProfileSources& sources, std::vector<std::string>& warnings) {
    auto registry = builtins();
    if (!registry) return registry.error();
    std::vector<fs::path> loaded;
    for (const std::string& path : sources.files) {
        if (loaded_already(loaded, path)) continue;
        auto entry = load_registered(path);
        if (!entry) return entry.error();
        if (auto added = registry->add(std::move(entry).value()); !added) return added.error();
    }
    if (sources.folder) {
        for (const fs::path& path : folder_profile_files(*sources.folder, warnings)) {
            if (loaded_already(loaded, path)) continue;
            auto entry = load_registered(path.string());
            if (!entry) {
                warnings.push_back(fmt::format("{}; this profile is not loaded", entry.error().message));
                registry->invalid_files_.push_back({path.string(), likely_profile_id(path), entry.error().message});
                continue;
            }
            if (auto added = registry->add(std::move(entry).value()); !added) return added.error();
        }
    }
    return registry;
}

Result<void> ProfileRegistry::add(RegisteredProfile entry) {
    const std::string& id = entry.profile->id;
    const auto place = std::lower_bound(profiles_.begin(), profiles_.end(), id,
                                        [](const RegisteredProfile& known, const std::string& wanted) { return known.profile->id < wanted; });
    if (place != profiles_.end() && place->profile->id == id) {
        return make_error(ErrorKind::usage,
                          fmt::format("profile id \"{}\" is defined twice, by {} and by {}; a file never replaces another "
                                      "profile: give one of them another \"id\", or remove it",
                                      id, describe_origin(place->origin), describe_origin(entry.origin)));
    }
    profiles_.insert(place, std::move(entry));
    return {};
}

Result<std::shared_ptr<const Profile>> ProfileRegistry::find(std::string_view id) const {
    const auto known = std::find_if(profiles_.begin(), profiles_.end(),
                                    [&](const RegisteredProfile& entry) { return entry.profile->id == id; });
    if (known != profiles_.end()) return known->profile;
    std::string message = fmt::format("unknown device \"{}\"; known profiles: {} (see `loopwire devices`; "
                                      "load another with --profile FILE.json)",
                                      id, fmt::join(ids(), ", "));
    for (const InvalidProfileFile& invalid : invalid_files_) {
        if (invalid.likely_id == id) {
            message += fmt::format("; the file {} that may define it is invalid: {}", invalid.path, invalid.problem);
        }
    }
    return make_error(ErrorKind::usage, message);
}

std::vector<std::string> ProfileRegistry::ids() const {
    std::vector<std::string> list;
    for (const RegisteredProfile& entry : profiles_) list.push_back(entry.profile->id);
    return list;
}

}  // namespace loopwire::device
