#include "app/profile_options.hpp"

#include <cstdlib>

#include <fmt/format.h>

namespace loopwire::app {

void ProfileOptions::add_to(CLI::App& app) {
    // One file per --profile, so `describe --profile f.json ID` leaves ID to describe.
    app.add_option("--profile", files,
                   "Load a device profile from this JSON file (repeatable); its id is then known like a built-in one. "
                   "Profiles in $XDG_CONFIG_HOME/loopwire/profiles (~/.config/loopwire/profiles) are loaded too")
        ->allow_extra_args(false)
        ->type_name("FILE.json");
    // Options a subcommand does not know are tried on the main command, so --profile may follow
    // the subcommand's name; subcommands added after this inherit it.
    app.fallthrough();
}

Result<device::ProfileRegistry> ProfileOptions::load() const {
    device::ProfileSources sources{files, device::user_profile_folder(std::getenv("XDG_CONFIG_HOME"), std::getenv("HOME"))};
    std::vector<std::string> warnings;
    auto registry = device::ProfileRegistry::build(sources, warnings);
    for (const std::string& warning : warnings) fmt::print(stderr, "loopwire: warning: {}\n", warning);
    return registry;
}

}  // namespace loopwire::app
