#pragma once
// Shared helpers of the device tests: the built-in profiles and files beside the repository.
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "profile/profile.hpp"
#include "profile/profile_registry.hpp"

namespace loopwire::device::testing {

inline const std::vector<std::string> profile_ids{"ac20", "rampsoak", "tc10"};

// Appended in place: GCC 12 reports a false -Warray-bounds on a chain of `+` over a temporary
// string once the TSan build inlines it (GCC bug 105329).
inline std::string profile_path(const std::string& id) {
    std::string path(LOOPWIRE_PROFILE_DIR);
    path.append("/").append(id).append(".json");
    return path;
}

// The file's text; an empty optional-like "" plus a failed assertion when it cannot be read.
inline bool read_text(const std::string& path, std::string& text) {
    std::ifstream file(path, std::ios::binary);
    if (!file) return false;
    std::ostringstream buffer;
    buffer << file.rdbuf();
    text = buffer.str();
    return true;
}

inline nlohmann::json read_json(const std::string& path) {
    std::string text;
    EXPECT_TRUE(read_text(path, text)) << "cannot read " << path;
    return nlohmann::json::parse(text);
}

// The built-in profile; the test fails (and the caller should stop) when it does not load.
inline std::shared_ptr<const Profile> builtin(const std::string& id) {
    auto profile = builtin_profile(id);
    EXPECT_TRUE(profile.ok()) << (profile.ok() ? "" : profile.error().message);
    return profile.ok() ? *profile : nullptr;
}

// The built-in profiles as a registry, loaded once (what a configuration is parsed against).
inline const ProfileRegistry& builtin_registry() {
    static const ProfileRegistry registry = [] {
        auto built = ProfileRegistry::builtins();
        if (!built) throw std::runtime_error(built.error().message);
        return std::move(built).value();
    }();
    return registry;
}

inline const Parameter& parameter(const Profile& profile, const std::string& name) {
    const Parameter* found = profile.find(name);
    if (found == nullptr) throw std::runtime_error("profile " + profile.id + " has no parameter " + name);
    return *found;
}

}  // namespace loopwire::device::testing
