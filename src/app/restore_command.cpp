// loopwire restore --link URL --device DEVICE@UNIT FILE [--dry-run] [--yes] [--force]
//                  [--security] [--lock-code N] [--control-code N]
// Writes a `loopwire dump` back: refuses another profile's or another device's dump unless
// --force, shows the differences, writes only what differs in the order and modes the manual
// requires (device/restore_plan.hpp), verifies every value by reading it back, and on any
// failure says exactly what was and was not written and returns the device to control mode.
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <string_view>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "client/dump_file.hpp"
#include "app/exit_codes.hpp"
#include "app/master_options.hpp"
#include "client/restore_runner.hpp"
#include "client/device_client.hpp"
#include "client/restore_plan.hpp"
#include "devices/registry.hpp"

namespace loopwire::app {
namespace {

struct RestoreCommandOptions {
    MasterCommandOptions master;
    std::string file;
    bool dry_run = false;
    bool yes = false;
    bool force = false;
    bool security = false;
    unsigned lock_code = 0;
    std::optional<unsigned> control_code;
};

std::string shown(const device::Parameter& parameter, std::uint16_t raw, const device::RawValues& known) {
    auto value = device::decode_value(parameter, raw, known);
    if (!value) return fmt::format("raw {}", raw);
    auto text = device::format_value(parameter, *value, known);
    return fmt::format("{}{} (raw {})", text ? *text : "?", value->unit.empty() ? "" : " " + value->unit, raw);
}

// The dump must come from this kind of device, and from this very device where the profile
// has identification words (AC20 120/121, TC10 20/21, ramp/soak VER).
Result<void> check_origin(const device::DumpFile& dump, const device::DeviceAddress& device, const device::RawValues& now, bool force) {
    if (dump.profile != device.profile->id && !force) {
        return make_error(ErrorKind::usage, fmt::format("the dump is of a {}, the device is a {}; add --force to write the "
                                                        "parameters they share anyway", dump.profile, device.profile->id));
    }
    for (const auto& [name, raw] : dump.identification) {
        const auto current = now.find(name);
        if (current == now.end() && !force) {
            return make_error(ErrorKind::usage, fmt::format("the device did not tell its {} (it refused the read): it cannot "
                                                            "be checked against the dump's; add --force to restore it anyway",
                                                            name));
        }
        if (current != now.end() && current->second != raw && !force) {
            return make_error(ErrorKind::usage, fmt::format("the dump's {} is {}, the device's is {}: it was taken from another "
                                                            "device or version; add --force to restore it anyway",
                                                            name, raw, current->second));
        }
    }
    return {};
}

// The present values of what restore may write, and the identification words. A device may
// refuse some words with an exception (an AC20 in a start-up error condition answers only its
// configuration, control and security words, which restore can then repair): a refused
// identification word is left out for check_origin to judge; any other failure ends here.
Result<device::RawValues> read_current(device::DeviceClient& client, const device::Profile& profile, const device::DumpFile& dump) {
    std::vector<const device::Parameter*> wanted;
    for (const device::Parameter& parameter : profile.parameters) {
        if (!parameter.readable) continue;
        const bool restorable = dump.values.contains(parameter.name) && device::is_restorable(parameter);
        if (restorable || dump.identification.contains(parameter.name)) wanted.push_back(&parameter);
    }
    auto report = client.read(wanted);
    for (const auto& reading : report.readings) {
        const bool refused_identification = report.first_error && report.first_error->kind == ErrorKind::exception &&
                                            dump.identification.contains(reading.parameter->name);
        if (report.raw.contains(reading.parameter->name) || refused_identification) continue;
        return make_error(report.first_error ? report.first_error->kind : ErrorKind::mismatch,
                          fmt::format("reading the device's present values failed at {}: {}", reading.parameter->name, reading.error));
    }
    return report.raw;
}

std::string counted(std::size_t count, std::string_view one, std::string_view many) {
    return fmt::format("{} {}", count, count == 1 ? one : many);
}

// Which side is which, so "25.0 -> 30.0" cannot be read backwards: the device's present value
// on the left, the file's (what a restore writes) on the right.
std::string differences_title(std::size_t count, const std::string& device, const std::string& file) {
    return fmt::format("{} between the device {} and the file {} (device now -> file, what restore writes):",
                       counted(count, "difference", "differences"), device, file);
}

void print_differences(const device::RestorePlan& plan, const device::RawValues& current, const device::RawValues& saved) {
    if (plan.changes.empty()) fmt::print("the device already holds every value of the dump\n");
    for (const auto& change : plan.changes) {
        fmt::print("  {:<34} {} -> {}\n", change.parameter->name, shown(*change.parameter, change.from, current),
                   shown(*change.parameter, change.to, saved));
    }
    for (const auto& skipped : plan.skipped) fmt::print("  not restored: {}\n", skipped);
}

Result<void> confirm(const RestoreCommandOptions& options, std::size_t changes) {
    if (options.yes) return {};
    if (!::isatty(STDIN_FILENO)) {
        return make_error(ErrorKind::usage, "not asking on a pipe: add --yes to write, or --dry-run to only show the differences");
    }
    fmt::print("write {} to {}? [y/N] ", counted(changes, "change", "changes"), options.master.device);
    std::fflush(stdout);
    std::string answer;
    std::getline(std::cin, answer);
    if (answer == "y" || answer == "Y" || answer == "yes") return {};
    return make_error(ErrorKind::usage, "nothing written (not confirmed)");
}

int run_restore(const RestoreCommandOptions& options, const ProfileOptions& profiles) {
    auto dump = device::read_dump_file(options.file);
    if (!dump) return report_error(dump.error());
    auto registry = profiles.load();
    if (!registry) return report_error(registry.error());
    auto device = device::parse_device_address(*registry, options.master.device, options.master.numbering);
    if (!device) return report_error(device.error());
    if (dump->profile == device->profile->id) {
        if (auto edited = device::check_texts_match_raw(*dump, *device->profile, options.file); !edited) {
            return report_error(edited.error());
        }
    }
    if (options.force) {  // names of another profile cannot be written; the shared ones can
        std::erase_if(dump->values, [&](const auto& entry) { return device->profile->find(entry.first) == nullptr; });
        std::erase_if(dump->identification, [&](const auto& entry) { return device->profile->find(entry.first) == nullptr; });
    }
    auto master = options.master.open();
    if (!master) return report_error(master.error());
    device::DeviceClient client(**master, *device);
    auto current = read_current(client, *device->profile, *dump);
    if (!current) return report_error(current.error());
    if (auto origin = check_origin(*dump, *device, *current, options.force); !origin) return report_error(origin.error());
    device::RestoreOptions restore_options;
    restore_options.include_security = options.security;
    restore_options.configuration_lock_code = static_cast<std::uint16_t>(options.lock_code);
    if (options.control_code) restore_options.control_lock_code = static_cast<std::uint16_t>(*options.control_code);
    auto plan = device::plan_restore(*device->profile, dump->values, *current, restore_options,
                                     device::models::restore_procedure_for(*device->profile));
    if (!plan) return report_error(plan.error());
    fmt::print("{}\n", differences_title(plan->changes.size(), options.master.device, options.file));
    print_differences(*plan, *current, dump->values);
    if (options.dry_run || plan->changes.empty()) {
        if (options.dry_run) fmt::print("dry run: nothing written\n");
        return exit_ok;
    }
    if (auto confirmed = confirm(options, plan->changes.size()); !confirmed) return report_error(confirmed.error());
    const device::RestoreOutcome outcome = device::execute_restore(client, *plan, stdout);
    if (outcome.error) {
        device::print_restore_failure(outcome, stderr);
        return exit_code_for(*outcome.error);
    }
    fmt::print("restored {}; every value read back as written\n", counted(plan->changes.size(), "parameter", "parameters"));
    return exit_ok;
}

}  // namespace

void add_restore_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<RestoreCommandOptions>();
    auto* command = app.add_subcommand("restore", "Write a `loopwire dump` back to a device, showing the differences first");
    options->master.add_to(*command, true);
    command->add_option("file", options->file, "Dump file written by `loopwire dump`")->required();
    command->add_flag("--dry-run", options->dry_run, "Only show the differences; write nothing");
    command->add_flag("--yes,-y", options->yes, "Write without asking");
    command->add_flag("--force", options->force, "Restore a dump of another profile or another device's identification");
    command->add_flag("--security", options->security, "AC20: also restore the security-code words 4000-4011");
    command->add_option("--lock-code", options->lock_code, "AC20: configuration lock combination for words 347/348 (default 0)")->check(CLI::Range(0, 250));
    command->add_option("--control-code", options->control_code, "AC20: control lock combination to unlock control parameters (word 349)")->check(CLI::Range(0, 250));
    command->footer(exit_code_help);
    command->callback([options, &exit_code, &profiles] { exit_code = run_restore(*options, profiles); });
}

}  // namespace loopwire::app
