#pragma once
// --profile FILE.json (repeatable, on every command) and the user's profile folder: the sources
// of the profile registry a command looks device ids up in.
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/result.hpp"
#include "profile/profile_registry.hpp"

namespace loopwire::app {

struct ProfileOptions {
    std::vector<std::string> files;

    // Adds --profile to `app`, where every subcommand accepts it, before or after its own name.
    void add_to(CLI::App& app);

    // The built-ins, the --profile files and every *.json in the user's profile folder
    // (device::user_profile_folder of XDG_CONFIG_HOME and HOME). Problems with folder files are
    // printed as warnings on stderr; a bad --profile file or a duplicate id is the error.
    Result<device::ProfileRegistry> load() const;
};

}  // namespace loopwire::app
