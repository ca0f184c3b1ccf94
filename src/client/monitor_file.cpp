#include "client/monitor_file.hpp"

#include <sys/stat.h>

#include <cctype>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

std::string extension_of(std::string_view path) {
    const std::string name = std::filesystem::path(path).filename().string();
    const auto dot = name.rfind('.');
    if (dot == std::string::npos || dot == 0) return {};
    std::string extension = name.substr(dot + 1);
    for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return extension;
}

const char* format_name(MonitorFormat format) {
    switch (format) {
        case MonitorFormat::table: return "table";
        case MonitorFormat::csv: return "csv";
        case MonitorFormat::jsonl: return "jsonl";
    }
    return "jsonl";
}

std::tm calendar(std::chrono::system_clock::time_point time, TimeStyle style) {
    const std::time_t seconds = std::chrono::system_clock::to_time_t(time);
    std::tm parts{};
    if (style == TimeStyle::utc) ::gmtime_r(&seconds, &parts);
    else ::localtime_r(&seconds, &parts);
    return parts;
}

bool same_day(std::chrono::system_clock::time_point a, std::chrono::system_clock::time_point b, TimeStyle style) {
    const std::tm x = calendar(a, style);
    const std::tm y = calendar(b, style);
    return x.tm_year == y.tm_year && x.tm_yday == y.tm_yday;
}

// The first line of `path`, with its line break.
std::string first_line(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::string line;
    std::getline(in, line);
    return in.eof() ? line : line + "\n";
}

std::string without_newline(std::string text) {
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
    return text;
}

}  // namespace

std::optional<MonitorFormat> format_of_extension(std::string_view path) {
    const std::string extension = extension_of(path);
    if (extension == "csv") return MonitorFormat::csv;
    if (extension == "jsonl" || extension == "ndjson") return MonitorFormat::jsonl;
    return std::nullopt;
}

Result<MonitorFormat> choose_monitor_format(std::string_view format_option, const std::string& output, bool stdout_terminal) {
    if (output.empty()) return monitor_format(format_option, stdout_terminal);
    const auto by_extension = format_of_extension(output);
    if (format_option.empty()) {
        if (by_extension) return *by_extension;
        return make_error(ErrorKind::usage, fmt::format("--output {}: cannot tell the format from its name; name it .csv, .jsonl or "
                                                        ".ndjson, or add --format csv or --format jsonl",
                                                        output));
    }
    auto format = monitor_format(format_option, false);
    if (!format) return format;
    if (*format == MonitorFormat::table) {
        return make_error(ErrorKind::usage, "the table redraws a terminal; write files as --format csv or jsonl");
    }
    if (by_extension && *by_extension != *format) {
        return make_error(ErrorKind::usage, fmt::format("--format {} contradicts --output {}, whose name says {}: drop one, or rename the file",
                                                        format_option, output, format_name(*by_extension)));
    }
    return format;
}

Result<std::uint64_t> parse_byte_size(std::string_view text, std::string_view option) {
    std::size_t digits = 0;
    while (digits < text.size() && std::isdigit(static_cast<unsigned char>(text[digits])) != 0) ++digits;
    const std::string_view unit = text.substr(digits);
    struct Unit {
        std::string_view name;
        std::uint64_t bytes;
    };
    static constexpr Unit units[] = {{"", 1},           {"B", 1},
                                     {"kB", 1000},      {"k", 1000},        {"KB", 1000},           {"KiB", 1024},
                                     {"MB", 1000000},   {"M", 1000000},     {"MiB", 1024 * 1024},
                                     {"GB", 1000000000}, {"G", 1000000000}, {"GiB", 1024 * 1024 * 1024}};
    const Unit* found = nullptr;
    for (const auto& candidate : units) {
        if (candidate.name == unit) found = &candidate;
    }
    std::uint64_t count = 0;
    bool overflow = false;
    for (std::size_t i = 0; i < digits; ++i) {
        overflow = overflow || count > (UINT64_MAX - 9) / 10;
        count = count * 10 + static_cast<std::uint64_t>(text[i] - '0');
    }
    if (digits == 0 || found == nullptr || overflow || count > UINT64_MAX / found->bytes) {
        return make_error(ErrorKind::usage, fmt::format("{} '{}' is not a size: write it like 10MB, 500kB, 1GiB or 65536", option, text));
    }
    const std::uint64_t bytes = count * found->bytes;
    if (bytes < 1000) return make_error(ErrorKind::usage, fmt::format("{} '{}' is too small: give at least 1kB (1000 bytes)", option, text));
    return bytes;
}

std::string rotated_name(const std::string& path, std::chrono::system_clock::time_point first_sample, bool daily, TimeStyle time) {
    const std::tm parts = calendar(first_sample, time);
    std::string stamp = fmt::format("{:04}-{:02}-{:02}", parts.tm_year + 1900, parts.tm_mon + 1, parts.tm_mday);
    if (!daily) stamp += fmt::format("T{:02}-{:02}-{:02}", parts.tm_hour, parts.tm_min, parts.tm_sec);
    const std::filesystem::path original(path);
    const std::string extension = original.extension().string();
    const std::string stem = (original.parent_path() / original.stem()).string();
    std::string name = fmt::format("{}.{}{}", stem, stamp, extension);
    for (unsigned index = 1; std::filesystem::exists(name); ++index) name = fmt::format("{}.{}.{}{}", stem, stamp, index, extension);
    return name;
}

namespace {

// A header's columns, split at the commas outside quotes.
std::vector<std::string> header_columns(const std::string& header) {
    std::vector<std::string> columns(1);
    bool quoted = false;
    for (const char c : without_newline(header)) {
        if (c == '"') quoted = !quoted;
        if (c == ',' && !quoted) {
            columns.emplace_back();
        } else {
            columns.back() += c;
        }
    }
    return columns;
}

// A column without " [unit]" takes the file's with or without one (see FileSampleSink::open).
bool same_columns(const std::string& file_header, const std::string& monitor_header) {
    const auto file = header_columns(file_header);
    const auto monitor = header_columns(monitor_header);
    if (file.size() != monitor.size()) return false;
    for (std::size_t i = 0; i < file.size(); ++i) {
        if (file[i] == monitor[i]) continue;
        const bool unit_free = monitor[i].find(" [") == std::string::npos;
        if (!unit_free || file[i].rfind(monitor[i] + " [", 0) != 0) return false;
    }
    return true;
}

}  // namespace

Result<std::unique_ptr<FileSampleSink>> FileSampleSink::open(const MonitorFileOptions& options, MonitorFormat format,
                                                             const std::string& csv_header) {
    struct stat status {};
    const bool exists = ::stat(options.path.c_str(), &status) == 0;
    const bool has_content = exists && S_ISREG(status.st_mode) && status.st_size > 0;
    std::string present;
    if (options.append && has_content && format == MonitorFormat::csv) {
        present = first_line(options.path);
        if (!same_columns(present, csv_header)) {
            return make_error(ErrorKind::usage,
                              fmt::format("--append {}: its CSV header differs from this monitor's columns, so the rows would not "
                                          "line up.\n  file:    {}\n  monitor: {}\nWatch the same devices and names, or write to a "
                                          "new file",
                                          options.path, without_newline(present), without_newline(csv_header)));
        }
    }
    std::FILE* file = std::fopen(options.path.c_str(), options.append ? "a" : "w");
    if (file == nullptr) {
        return make_error(ErrorKind::usage, fmt::format("cannot write {}: {}", options.path, std::strerror(errno)));
    }
    const std::uint64_t size = options.append && has_content ? static_cast<std::uint64_t>(status.st_size) : 0;
    // An appended file started on the day it was last written.
    std::optional<std::chrono::system_clock::time_point> started;
    if (size > 0) started = std::chrono::system_clock::from_time_t(status.st_mtim.tv_sec);
    return std::unique_ptr<FileSampleSink>(
        new FileSampleSink(options, format, format == MonitorFormat::csv ? csv_header : "", file, size, started, present));
}

FileSampleSink::FileSampleSink(MonitorFileOptions options, MonitorFormat format, std::string csv_header, std::FILE* file,
                               std::uint64_t size, std::optional<std::chrono::system_clock::time_point> started,
                               std::string appended_header)
    : options_(std::move(options)),
      format_(format),
      csv_header_(std::move(csv_header)),
      file_(file),
      size_(size),
      started_(started),
      appended_header_(std::move(appended_header)) {}

// Once, at the first sample appended: the columns whose unit the device now reports differently
// from the file's header (a header without units, or °C where the device now says °F).
void FileSampleSink::explain_units(const std::string& header) {
    const auto file = header_columns(appended_header_);
    const auto now = header_columns(header);
    appended_header_.clear();
    if (file.size() != now.size()) return;
    for (std::size_t i = 0; i < file.size(); ++i) {
        if (file[i] == now[i]) continue;
        fmt::print(stderr, "loopwire: warning: --append {}: the file's column \"{}\" is now \"{}\": the rows appended are in "
                           "the unit the device reports now; start a new file to keep one unit a column\n",
                   options_.path, file[i], now[i]);
    }
}

FileSampleSink::~FileSampleSink() {
    if (file_ != nullptr) std::fclose(file_);
}

bool FileSampleSink::needs_rotation(std::chrono::system_clock::time_point time, std::size_t bytes) const {
    if (size_ == 0 || rotation_failed_) return false;  // an empty file takes any sample
    if (options_.rotate_size && size_ + bytes > *options_.rotate_size) return true;
    return options_.rotate_daily && started_ && !same_day(*started_, time, options_.time);
}

void FileSampleSink::rotate(std::chrono::system_clock::time_point time) {
    std::fflush(file_);
    const std::string target = rotated_name(options_.path, started_.value_or(time), options_.rotate_daily, options_.time);
    std::error_code error;
    std::filesystem::rename(options_.path, target, error);
    std::FILE* fresh = error ? nullptr : std::fopen(options_.path.c_str(), "w");
    if (fresh == nullptr) {
        const std::string why = error ? error.message() : std::strerror(errno);
        if (!error) std::filesystem::rename(target, options_.path, error);  // the old file back under its name
        fmt::print(stderr, "loopwire: warning: cannot rotate {} to {}: {}; writing on in {}\n", options_.path, target, why, options_.path);
        rotation_failed_ = true;
        return;
    }
    std::fclose(file_);
    file_ = fresh;
    size_ = 0;
    started_.reset();
}

void FileSampleSink::write(const SampleView& sample) {
    const std::string header = format_ == MonitorFormat::csv ? csv_header(*sample.devices) : "";
    if (!appended_header_.empty()) explain_units(header);
    write_text(sample.time, sample.index, record_line(sample, format_, options_.time, false), header);
}

void FileSampleSink::write_row(std::chrono::system_clock::time_point time, unsigned index, const std::string& row) {
    write_text(time, index, row, csv_header_);
}

void FileSampleSink::write_text(std::chrono::system_clock::time_point time, unsigned index, const std::string& row,
                                const std::string& header) {
    // The row alone decides whether a file is full; the header a new file starts with is not
    // counted against the sample that follows it.
    if (needs_rotation(time, row.size())) rotate(time);
    const std::string text = size_ == 0 ? header + row : row;
    if (std::fputs(text.c_str(), file_) < 0 || std::fflush(file_) != 0) {
        fmt::print(stderr, "loopwire: warning: writing sample {} to {} failed: {}\n", index, options_.path, std::strerror(errno));
        return;
    }
    size_ += text.size();
    if (!started_) started_ = time;
}

}  // namespace loopwire::device
