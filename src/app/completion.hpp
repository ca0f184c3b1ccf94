#pragma once
// Shell completion answered from the command-line definitions themselves: the bash and zsh
// scripts (packaging/completion/) pass the words typed so far to `loopwire __complete` and offer
// what it prints, so a new command or option is completed without touching the scripts.
#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/result.hpp"
#include "profile/profile_registry.hpp"

namespace loopwire::app {

struct Completion {
    bool files = false;               // the word is a path: the shell completes file names
    std::vector<std::string> words;   // otherwise these, sorted, each starting with the word typed
};

// The profiles known with these --profile files (and the user's folder), for device ids and
// parameter names.
using ProfileLoader = std::function<Result<device::ProfileRegistry>(const std::vector<std::string>& profile_files)>;

// `words`: what follows `loopwire` on the line, up to the word being completed (the last one,
// possibly empty).
Completion complete_command_line(const CLI::App& root, const std::vector<std::string>& words, const ProfileLoader& load_profiles);

}  // namespace loopwire::app
