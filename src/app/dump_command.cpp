// loopwire dump --link URL --device DEVICE@UNIT [--numbering jbus] [--output FILE]
// Every readable parameter of one device into one JSON document (format: device::dump_document.hpp).
#include <unistd.h>

#include <algorithm>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common/atomic_file.hpp"
#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "client/dump_document.hpp"
#include "app/exit_codes.hpp"
#include "app/master_options.hpp"
#include "common/time_text.hpp"
#include "client/restore_plan.hpp"

namespace loopwire::app {
namespace {

struct DumpOptions {
    MasterCommandOptions master;
    std::string output;
};

// Reads block by block (the planner's blocks), so progress can be shown between requests. A
// block the device refuses with an exception (an AC20 in a start-up error condition answers
// only its configuration, control and security words) is kept as unread and the dump goes on;
// any other failure (no reply, a broken link) ends it: a partial dump is worse than none.
Result<device::ReadReport> read_everything(device::DeviceClient& client) {
    const auto& device = client.device();
    const auto blocks = device::plan_reads(*device.profile, device::dumped_parameters(*device.profile), device.address_offset);
    const bool progress = ::isatty(STDERR_FILENO) == 1;
    device::ReadReport all;
    std::size_t done = 0;
    for (std::size_t i = 0; i < blocks.size(); ++i) {
        auto part = client.read(blocks[i].parameters);
        if (part.first_error && part.first_error->kind != ErrorKind::exception) {
            if (progress) fmt::print(stderr, "\n");
            return make_error(part.first_error->kind, fmt::format("dump stopped at {} {}..: {}", device::table_name(blocks[i].table),
                                                                  blocks[i].wire_address, part.first_error->message));
        }
        if (part.first_error && !all.first_error) all.first_error = part.first_error;
        done += part.readings.size();
        all.readings.insert(all.readings.end(), part.readings.begin(), part.readings.end());
        all.raw.insert(part.raw.begin(), part.raw.end());
        all.requests += part.requests;
        if (progress) fmt::print(stderr, "\r  block {}/{}, {} parameters read   ", i + 1, blocks.size(), done);
    }
    if (progress) fmt::print(stderr, "\n");
    return all;
}

// What the device refused must not be something restore would write back: such a dump is not
// a backup. Refused live values (process values, status words) are only reported. A word that
// was read but cannot be decoded (its decimals word holds nonsense) is no refusal: the dump
// keeps the word, which is all restore needs, and marks it "undecodable".
Result<void> check_refusals(const device::ReadReport& report) {
    std::vector<std::string> stored, live, undecodable;
    std::string reason, undecodable_reason;
    for (const auto& reading : report.readings) {
        if (reading.value) continue;
        if (report.raw.contains(reading.parameter->name)) {
            undecodable.push_back(reading.parameter->name);
            if (undecodable_reason.empty()) undecodable_reason = reading.error;
            continue;
        }
        (device::is_restorable(*reading.parameter) ? stored : live).push_back(reading.parameter->name);
        if (reason.empty()) reason = reading.error;
    }
    if (!undecodable.empty()) {
        fmt::print(stderr, "loopwire: warning: {} value(s) read but not decodable ({}), kept as raw words and marked "
                           "\"status\": \"undecodable\" in the dump: {}\n",
                   undecodable.size(), fmt::join(undecodable, ", "), undecodable_reason);
    }
    if (!stored.empty()) {
        return make_error(ErrorKind::exception, fmt::format("the device refused to read {} stored parameter(s) ({}): {}; "
                                                            "no dump written, as it could not restore them",
                                                            stored.size(), fmt::join(stored, ", "), reason));
    }
    if (!live.empty()) {
        fmt::print(stderr, "loopwire: warning: the device refused {} live value(s) ({}), marked \"status\": \"unread\" "
                           "in the dump: {}; every stored parameter was read\n",
                   live.size(), fmt::join(live, ", "), reason);
    }
    return {};
}

// The readings in the profile's order, whatever order the blocks came in.
void sort_by_profile(device::ReadReport& report, const device::Profile& profile) {
    const auto position = [&profile](const device::Parameter* p) { return p - profile.parameters.data(); };
    std::stable_sort(report.readings.begin(), report.readings.end(),
                     [&](const auto& a, const auto& b) { return position(a.parameter) < position(b.parameter); });
}

int run_dump(const DumpOptions& options, const ProfileOptions& profiles) {
    auto registry = profiles.load();
    if (!registry) return report_error(registry.error());
    auto device = device::parse_device_address(*registry, options.master.device, options.master.numbering);
    if (!device) return report_error(device.error());
    if (!options.output.empty()) {  // before the reading, which takes long, not after it
        if (auto writable = check_writable_atomically(options.output); !writable) return report_error(writable.error());
    }
    auto master = options.master.open();
    if (!master) return report_error(master.error());
    const auto time = iso8601_utc(std::chrono::system_clock::now());
    device::DeviceClient client(**master, *device);
    auto report = read_everything(client);
    if (!report) return report_error(report.error());
    if (auto refused = check_refusals(*report); !refused) return report_error(refused.error());
    sort_by_profile(*report, *device->profile);
    auto document = device::dump_document(*device, device::DumpHeader{options.master.link, time, options.master.numbering}, *report);
    if (!document) return report_error(document.error());
    const std::string text = document->dump(2) + "\n";
    if (options.output.empty()) {
        fmt::print("{}", text);
        return exit_ok;
    }
    // A dump holds the AC20's lock combinations: a new file is readable by its owner only.
    // An earlier dump killed half-way may have left its temporary: it is of no use now.
    remove_stale_temporaries(options.output);
    if (auto written = write_file_atomically(options.output, text, private_file_mode); !written) return report_error(written.error());
    fmt::print(stderr, "loopwire: {} parameters of {}@{} written to {}\n", report->readings.size(), device->profile->id,
               device->unit, options.output);
    return exit_ok;
}

}  // namespace

void add_dump_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<DumpOptions>();
    auto* command = app.add_subcommand("dump", "Read every readable parameter of a device into one JSON document (for restore)");
    command->add_option("--link", options->master.link, "Link URL (see `loopwire read --help`)")->required();
    command->add_option("--device", options->master.device, "DEVICE@UNIT (e.g. tc10@3)")->required();
    command->add_option("--numbering", options->master.numbering, "The device's alternative numbering in use (ac20: jbus)");
    command->add_option("--output", options->output, "Write the document to FILE (atomically: all of it or nothing; a new file is private to you, an existing one keeps "
                        "its mode and owner, a link is followed, a FIFO or device such as /dev/stdout is written into); default stdout");
    command->add_option("--timeout", options->master.timeout, "Time to wait for each reply")->capture_default_str();
    command->add_option("--retries", options->master.retries, "Extra tries after a timeout or a reply refused as a probable copy")->capture_default_str();
    command->add_flag("-v,--verbose", options->master.verbose, "Print every frame sent and received, with timestamps, on stderr");
    command->footer(exit_code_help);
    command->callback([options, &exit_code, &profiles] { exit_code = run_dump(*options, profiles); });
}

}  // namespace loopwire::app
