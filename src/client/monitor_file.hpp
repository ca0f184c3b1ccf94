#pragma once
// Monitor logs that run unattended: the format named by the file's extension, appending to an
// existing log (its CSV header checked), and rotation by size or by day with nothing lost at
// the switch.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "client/monitor_records.hpp"
#include "common/result.hpp"

namespace loopwire::device {

// The format of --output FILE's extension: .csv, .jsonl or .ndjson; nothing for others.
std::optional<MonitorFormat> format_of_extension(std::string_view path);

// --format and --output together: a --format wins for an unknown extension, an extension chooses
// when --format is absent, and the two must agree when both speak. Without --output: the
// table on a terminal, JSON lines otherwise. A file never gets the table.
Result<MonitorFormat> choose_monitor_format(std::string_view format_option, const std::string& output, bool stdout_terminal);

// "10MB", "500kB", "1GiB", "2048": bytes (kB/MB/GB are powers of 1000, KiB/MiB/GiB of 1024).
Result<std::uint64_t> parse_byte_size(std::string_view text, std::string_view option);

struct MonitorFileOptions {
    std::string path;
    bool append = false;                      // add to an existing file instead of replacing it
    std::optional<std::uint64_t> rotate_size;  // start a new file before one would pass this size
    bool rotate_daily = false;                // start a new file at each new day (local or UTC, as `time`)
    TimeStyle time = TimeStyle::local;
};

// The name a finished file is moved to: STEM.STAMP.EXT next to it, where STAMP is the day of its
// first sample (daily) or its date and time ("2026-12-01T13-45-10"); ".1", ".2"... before the
// extension when that name is taken.
std::string rotated_name(const std::string& path, std::chrono::system_clock::time_point first_sample, bool daily,
                         TimeStyle time);

// Writes samples to a file, flushed per sample. The CSV header starts every file (new, or empty
// when appended to); a file that is rotated is renamed (rotated_name) and a fresh one started
// under the same name before the sample that would overflow it or that starts a new day, so
// every sample lands whole in exactly one file. A failure to rotate is reported on stderr once
// and writing goes on in the current file: a log that grows beats a log that loses samples.
class FileSampleSink final : public SampleSink {
public:
    // `csv_header` is the header this monitor writes (empty for JSON lines): with --append, an
    // existing non-empty file must start with it, or this fails saying how they differ. A column
    // without a unit in it stands for a unit the device's configuration sets, not yet read: it
    // matches the file's column with or without one, and the first sample tells (on stderr) when
    // the unit the device now reports is not the one the file's header says.
    static Result<std::unique_ptr<FileSampleSink>> open(const MonitorFileOptions& options, MonitorFormat format,
                                                        const std::string& csv_header);
    ~FileSampleSink() override;
    FileSampleSink(const FileSampleSink&) = delete;
    FileSampleSink& operator=(const FileSampleSink&) = delete;

    void write(const SampleView& sample) override;
    // One sample as text, for monitors whose samples are not SampleViews (raw registers): `row`,
    // preceded by the CSV header when it starts a file.
    void write_row(std::chrono::system_clock::time_point time, unsigned index, const std::string& row);

private:
    FileSampleSink(MonitorFileOptions options, MonitorFormat format, std::string csv_header, std::FILE* file, std::uint64_t size,
                   std::optional<std::chrono::system_clock::time_point> started, std::string appended_header);
    void explain_units(const std::string& header);
    bool needs_rotation(std::chrono::system_clock::time_point time, std::size_t bytes) const;
    void rotate(std::chrono::system_clock::time_point time);
    void write_text(std::chrono::system_clock::time_point time, unsigned index, const std::string& row, const std::string& header);

    MonitorFileOptions options_;
    MonitorFormat format_;
    std::string csv_header_;  // what each CSV file starts with; empty for JSON lines
    std::FILE* file_;
    std::uint64_t size_;
    std::optional<std::chrono::system_clock::time_point> started_;  // time of the file's first sample
    bool rotation_failed_ = false;
    // The header of the file appended to, until the first sample's units are compared with it.
    std::string appended_header_;
};

}  // namespace loopwire::device
