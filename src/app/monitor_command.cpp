// loopwire monitor --link URL --device DEVICE@UNIT [--device ...] [NAMES...] [--interval 1s]
//                  [--format table|csv|jsonl] [--count N] [--output FILE [--append] [--rotate-size 10MB]
//                  [--rotate daily]] [--utc]
//                  --link URL --unit N TABLE ADDRESS [COUNT] [--type T ...] (raw_monitor.hpp)
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <limits>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/monitor_output.hpp"
#include "app/monitor_screen.hpp"
#include "app/master_options.hpp"
#include "app/raw_monitor.hpp"
#include "client/monitor_file.hpp"
#include "client/monitor_loop.hpp"
#include "client/monitor_names.hpp"
#include "app/stop_signal.hpp"

namespace loopwire::app {
namespace {

struct MonitorOptions {
    MasterCommandOptions master;
    RawTypeOptions typing;  // raw registers, without --device
    std::vector<std::string> devices;
    std::vector<std::string> names;  // or TABLE ADDRESS [COUNT] without --device
    std::string interval = "1s";
    std::string format;  // empty: table on a terminal, jsonl otherwise
    unsigned count = 0;  // 0: until stopped
    std::string output;
    bool append = false;
    std::string rotate_size;
    std::string rotate;
    bool utc = false;
};

Result<MonitorFormat> choose_format(const MonitorOptions& options) {
    const bool terminal = options.output.empty() && ::isatty(STDOUT_FILENO) == 1;
    return device::choose_monitor_format(options.format, options.output, terminal);
}

TimeStyle time_style(const MonitorOptions& options) { return options.utc ? TimeStyle::utc : TimeStyle::local; }

Result<device::MonitorFileOptions> file_options(const MonitorOptions& options) {
    if (options.output.empty() && (options.append || !options.rotate_size.empty() || !options.rotate.empty())) {
        return make_error(ErrorKind::usage, "--append, --rotate-size and --rotate apply to a log file: add --output FILE");
    }
    device::MonitorFileOptions file{options.output, options.append, std::nullopt, false, time_style(options)};
    if (!options.rotate_size.empty()) {
        auto size = device::parse_byte_size(options.rotate_size, "--rotate-size");
        if (!size) return size.error();
        file.rotate_size = *size;
    }
    if (!options.rotate.empty() && options.rotate != "daily") {
        return make_error(ErrorKind::usage, fmt::format("--rotate '{}': the one period is daily (or use --rotate-size)", options.rotate));
    }
    file.rotate_daily = options.rotate == "daily";
    return file;
}

// The columns the CSV of these devices has, known before the first sample (--append checks them).
std::string planned_csv_header(const std::vector<device::DeviceAddress>& devices, const std::vector<std::vector<const device::Parameter*>>& lists) {
    std::vector<device::WatchedDevice> watched;
    for (std::size_t i = 0; i < devices.size(); ++i) {
        watched.push_back(device::watch(fmt::format("{}@{}", devices[i].profile->id, devices[i].unit), lists[i]));
    }
    return csv_header(watched);
}

Result<device::MonitorSettings> settings_of(const MonitorOptions& options) {
    auto interval = parse_duration(options.interval, "--interval", std::chrono::milliseconds(10));
    if (!interval) return interval.error();
    const auto millis = std::chrono::duration_cast<std::chrono::milliseconds>(*interval);
    device::MonitorSettings settings;
    settings.interval = millis;
    if (options.count > 0) settings.count = options.count;
    return settings;
}

Result<std::vector<device::DeviceAddress>> parse_devices(const device::ProfileRegistry& profiles, const std::vector<std::string>& texts) {
    std::vector<device::DeviceAddress> devices;
    for (const auto& text : texts) {
        auto device = device::parse_device_address(profiles, text);
        if (!device) return device.error();
        for (const auto& seen : devices) {
            if (seen.unit == device->unit) return make_error(ErrorKind::usage, fmt::format("two --device options name unit {}", seen.unit));
        }
        devices.push_back(std::move(*device));
    }
    return devices;
}

int run_monitor_command(const MonitorOptions& options, const ProfileOptions& profiles) {
    auto settings = settings_of(options);
    if (!settings) return report_error(settings.error());
    auto format = choose_format(options);
    if (!format) return report_error(format.error());
    auto file_settings = file_options(options);
    if (!file_settings) return report_error(file_settings.error());
    if (options.devices.empty()) return run_raw_monitor(options.master, options.typing, options.names, *settings, *format, *file_settings);
    if (options.typing.any_given()) return report_error(RawTypeOptions::not_with_names());
    auto registry = profiles.load();
    if (!registry) return report_error(registry.error());
    auto devices = parse_devices(*registry, options.devices);
    if (!devices) return report_error(devices.error());
    auto lists = device::watch_lists(*devices, options.names);
    if (!lists) return report_error(lists.error());
    std::unique_ptr<device::SampleSink> sink;
    if (!options.output.empty()) {
        auto file = device::FileSampleSink::open(*file_settings, *format, *format == MonitorFormat::csv ? planned_csv_header(*devices, *lists) : "");
        if (!file) return report_error(file.error());
        sink = std::move(*file);
    } else if (*format != MonitorFormat::table) {
        sink = std::make_unique<StreamSampleSink>(stdout, *format, time_style(options));
    }
    std::unique_ptr<TableScreen> screen;
    device::TraceSink trace;
    if (!sink) {  // the live table on stdout's terminal; -v traces above it when stderr is a terminal too
        screen = std::make_unique<TableScreen>(stdout);
        sink = std::make_unique<TerminalTableSink>(*screen, STDOUT_FILENO, time_style(options));
        if (::isatty(STDERR_FILENO) == 1) trace = screen->trace_sink();
    }
    StopSignal stop;  // before the master's threads start, so they inherit the blocked signals
    auto master = options.master.open(trace);
    if (!master) return report_error(master.error());
    std::vector<device::MonitorTarget> targets;
    for (std::size_t i = 0; i < devices->size(); ++i) targets.push_back(device::MonitorTarget{master->get(), (*devices)[i], (*lists)[i], {}, !options.master.no_identify});
    device::run_monitor(targets, *settings, *sink, stop.token());
    return exit_ok;
}

}  // namespace

void add_monitor_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<MonitorOptions>();
    options->master.timeout = "500ms";
    options->master.unit = 0;  // not given: raw registers need --unit  // below the default interval, so a dead unit does not stretch a sample
    auto* command = app.add_subcommand("monitor", "Poll devices on one link and show their values live, or stream them as CSV / JSON lines");
    command->add_option("--link", options->master.link, "Link URL (see `loopwire read --help`); all devices share it")->required();
    auto* device = command->add_option("--device", options->devices, "DEVICE@UNIT to poll (repeat for several units on the link)")
                       ->allow_extra_args(false);  // one value per --device, so NAMES after it stay NAMES
    command->add_option("--unit", options->master.unit, "Unit id of a device without a profile: poll raw registers TABLE ADDRESS [COUNT]")
        ->check(CLI::Range(1, 247))
        ->excludes(device);
    command->add_option("names", options->names,
                        "What to watch: NAME (a name, mnemonic, group or all) on every device, an error where one has no "
                        "such name, or DEVICE@UNIT:NAME for one device. A device no NAME applies to shows its default set: "
                        "process value, set point, output, alarm/status. With --unit instead of --device: " +
                            std::string(raw_count_help));
    options->typing.add_to(*command);
    command->add_option("--interval", options->interval, "Time between samples: 500ms, 2s, ...")->capture_default_str();
    command->add_option("--format", options->format,
                        "table (live, redrawn in place), csv or jsonl (one line per sample, ISO 8601 time). "
                        "Default: from --output's extension (.csv, .jsonl, .ndjson); else table when stdout is a terminal, jsonl otherwise");
    // 0 would read as "none", yet meant "until Ctrl-C": refused, as the other commands refuse it.
    command->add_option("--count", options->count, "Stop after N samples (default: until Ctrl-C)")
        ->check(CLI::Range(1u, std::numeric_limits<unsigned>::max()));
    command->add_option("--output", options->output, "Write samples to FILE (csv or jsonl, chosen by its extension) instead of stdout; it is replaced unless --append");
    command->add_flag("--append", options->append, "Add to FILE instead of replacing it (a CSV file must have the same columns; its header is kept)");
    command->add_option("--rotate-size", options->rotate_size, "Start a new FILE before it would pass this size (10MB, 500kB, 1GiB); the full one is renamed FILE-STEM.DATE-TIME.EXT");
    command->add_option("--rotate", options->rotate, "daily: start a new FILE on each new day; the finished one is renamed FILE-STEM.DATE.EXT");
    command->add_flag("--utc", options->utc, "Write times in UTC (...Z) instead of local time with its offset (...+01:00)");
    command->add_option("--timeout", options->master.timeout, "Time to wait for each reply")->capture_default_str();
    command->add_option("--retries", options->master.retries, "Extra tries after a timeout or a reply refused as a probable copy")->capture_default_str();
    options->master.add_identify_to(*command);
    command->add_flag("-v,--verbose", options->master.verbose,
                      "Print every frame sent and received, with timestamps, on stderr (above the table, which is redrawn "
                      "under them, when both are on the terminal)");
    command->footer(std::string("A unit that stops answering shows status no-reply (then waiting) and is retried after one "
                                "interval, doubling up to 30s; values not read in a sample are shown with their age, "
                                "never as current. A unit whose identification words (read with the first poll and the first after "
                                "an outage) say it is another device shows wrong-device, and none of its words as values.\n") +
                    exit_code_help);
    command->callback([options, &exit_code, &profiles] { exit_code = run_monitor_command(*options, profiles); });
}

}  // namespace loopwire::app
