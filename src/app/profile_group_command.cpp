// loopwire profile from-points FILE DEVICE [--out FILE.json]
// Commands that make profiles. from-points: the profile a device described by its points in a
// gateway configuration stands for, as a profile file, so that it can be used with --profile by
// read, write, monitor and simulate, shared, or extended by hand.
#include <memory>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "common/atomic_file.hpp"
#include "gateway/device_points.hpp"

namespace loopwire::app {
namespace {

struct FromPointsOptions {
    std::string config;
    std::string device;
    std::string out;
};

int run_from_points(const FromPointsOptions& options) {
    auto text = gateway::points_profile_text(options.config, options.device);
    if (!text) return report_error(text.error());
    if (options.out.empty()) {
        fmt::print("{}", *text);
        return exit_ok;
    }
    if (auto written = write_file_atomically(options.out, *text); !written) return report_error(written.error());
    return exit_ok;
}

}  // namespace

void add_profile_group_command(CLI::App& app, int& exit_code) {
    auto* group = app.add_subcommand("profile", "Make device profiles: `profile from-points` writes the profile of a device "
                                                "described by its points in a gateway configuration");
    group->require_subcommand(1);
    auto options = std::make_shared<FromPointsOptions>();
    auto* from_points = group->add_subcommand(
        "from-points", "Write the JSON profile of a device described by [[lines.devices.points]] in a gateway "
                       "configuration (to stdout, or --out FILE); load it with --profile FILE");
    from_points->add_option("config", options->config, "The gateway configuration (TOML)")->type_name("FILE")->required();
    from_points->add_option("device", options->device, "The device's name in it")->type_name("DEVICE")->required();
    from_points->add_option("--out", options->out, "Write the profile to this file instead of stdout")->type_name("FILE");
    from_points->footer(exit_code_help);
    from_points->callback([options, &exit_code] { exit_code = run_from_points(*options); });
}

}  // namespace loopwire::app
