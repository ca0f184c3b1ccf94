#pragma once
// The profiles one run of loopwire knows: the built-ins plus profile files found at run time
// (named on the command line, or in the user's profile folder). Built once from its sources and
// immutable afterwards; whoever needs a profile by id is handed the registry (docs/DESIGN.md,
// "As built"), there is no process-wide list to change.
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/result.hpp"
#include "profile/profile.hpp"

namespace loopwire::device {

inline constexpr std::string_view builtin_origin = "built-in";

struct RegisteredProfile {
    std::shared_ptr<const Profile> profile;
    std::string origin;  // builtin_origin, or the path of the file it was loaded from
};

// A file of the profile folder that could not be used, and the id it seems to define (from its
// "id" member when that is readable, else its file name without ".json").
struct InvalidProfileFile {
    std::string path;
    std::string likely_id;
    std::string problem;
};

struct ProfileSources {
    std::vector<std::string> files;     // must each load (--profile): any problem is an error
    std::optional<std::string> folder;  // every *.json in it; problems are warnings
};

// Where the user's profiles live: $XDG_CONFIG_HOME/loopwire/profiles, or
// $HOME/.config/loopwire/profiles when XDG_CONFIG_HOME is unset or empty; nothing when neither
// is known. The arguments are the variables' values (null when unset).
std::optional<std::string> user_profile_folder(const char* xdg_config_home, const char* home);

class ProfileRegistry {
public:
    // The built-in profiles only.
    static Result<ProfileRegistry> builtins();

    // The built-ins plus `sources`. Fails (ErrorKind::usage) when a named file cannot be loaded
    // or when two profiles share an id (a file never replaces a built-in or another file: the
    // message names both, so the user can rename the id or remove one). A folder that cannot be
    // read and a folder file that does not load are appended to `warnings` and skipped.
    static Result<ProfileRegistry> build(const ProfileSources& sources, std::vector<std::string>& warnings);

    // The profile with this id; when unknown, the error lists the known ids and names an invalid
    // folder file that may have defined it.
    Result<std::shared_ptr<const Profile>> find(std::string_view id) const;

    const std::vector<RegisteredProfile>& profiles() const { return profiles_; }  // sorted by id
    std::vector<std::string> ids() const;
    const std::vector<InvalidProfileFile>& invalid_files() const { return invalid_files_; }

private:
    Result<void> add(RegisteredProfile entry);

    std::vector<RegisteredProfile> profiles_;
    std::vector<InvalidProfileFile> invalid_files_;
};

}  // namespace loopwire::device
