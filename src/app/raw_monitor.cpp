#include "app/raw_monitor.hpp"

#include <cerrno>
#include <cstring>
#include <memory>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/exit_codes.hpp"
#include "app/stop_signal.hpp"
#include "client/register_monitor.hpp"
#include "common/time_text.hpp"

namespace loopwire::app {
namespace {

std::string status_of(const Error& error) {
    switch (error.kind) {
        case ErrorKind::timeout:
        case ErrorKind::link: return "no-reply";
        case ErrorKind::exception: return "exception";
        default: return "error";
    }
}

// The first address of every value, in the --base numbering.
std::vector<unsigned> value_addresses(const RawRequest& request) {
    std::vector<unsigned> addresses;
    const unsigned each = device::registers_per_value(request.layout.type);
    for (unsigned i = 0; i < request.count; ++i) addresses.push_back(request.address + i * each);
    return addresses;
}

std::string typing_text(const RawRequest& request) {
    std::string text(device::raw_type_name(request.layout.type));
    if (device::registers_per_value(request.layout.type) > 1) text += fmt::format(", {} word order", device::word_order_name(request.layout.word_order));
    if (request.layout.byte_swap) text += ", bytes swapped";
    if (request.scale) text += fmt::format(", scaled by {}", device::number_text(device::scaled(std::int64_t{1}, *request.scale)));
    if (request.base != 0) text += ", 1-based addresses";
    return text;
}

class RawSampleWriter {
public:
    // Samples go to `file` when given (appended, rotated: monitor_file.hpp), else to `out`.
    RawSampleWriter(const RawRequest& request, int unit, MonitorFormat format, std::FILE* out, device::FileSampleSink* file)
        : request_(request), unit_(unit), format_(format), out_(out), file_(file) {}
    ~RawSampleWriter() {
        if (format_ == MonitorFormat::table && shown_lines_ > 0) {
            std::fputs(terminal_restore, out_);
            std::fflush(out_);
        }
    }
    RawSampleWriter(const RawSampleWriter&) = delete;
    RawSampleWriter& operator=(const RawSampleWriter&) = delete;

    void write(const RawSample& sample) {
        if (file_ != nullptr) {
            file_->write_row(sample.time, sample.index, format_ == MonitorFormat::jsonl ? raw_sample_json(request_, unit_, sample).dump() + "\n"
                                                                                        : raw_csv_row(request_, sample));
            return;
        }
        std::string text;
        if (format_ == MonitorFormat::jsonl) text = raw_sample_json(request_, unit_, sample).dump() + "\n";
        else if (format_ == MonitorFormat::csv) text = (sample.index == 1 ? raw_csv_header(request_) : "") + raw_csv_row(request_, sample);
        else {
            const auto lines = raw_table_lines(request_, unit_, sample);
            text = table_frame(lines, shown_lines_);
            shown_lines_ = lines.size();
        }
        std::fputs(text.c_str(), out_);
        std::fflush(out_);
    }

private:
    const RawRequest& request_;
    int unit_;
    MonitorFormat format_;
    std::FILE* out_;
    device::FileSampleSink* file_;
    std::size_t shown_lines_ = 0;
};

}  // namespace

nlohmann::ordered_json raw_sample_json(const RawRequest& request, int unit, const RawSample& sample) {
    nlohmann::ordered_json out{{"time", iso8601(sample.time, sample.utc)}, {"sample", sample.index}, {"unit", unit},
                               {"table", request.table->name}};
    describe_typing(request, out);
    out["status"] = sample.status;
    out["errors"] = sample.errors;
    if (sample.status != "ok") out["error"] = sample.error;
    nlohmann::ordered_json values = nlohmann::ordered_json::object();
    for (const auto address : value_addresses(request)) values[std::to_string(address)] = nullptr;
    for (const auto& reading : sample.readings) values[std::to_string(reading.address)] = number_json(reading.number);
    out["values"] = values;
    return out;
}

std::string raw_csv_header(const RawRequest& request) {
    std::vector<std::string> columns{"time", "sample", "status", "errors"};
    for (const auto address : value_addresses(request)) columns.push_back(fmt::format("{} {}", request.table->name, address));
    return fmt::format("{}\n", fmt::join(columns, ","));
}

std::string raw_csv_row(const RawRequest& request, const RawSample& sample) {
    std::vector<std::string> fields{iso8601(sample.time, sample.utc), std::to_string(sample.index), sample.status, std::to_string(sample.errors)};
    std::vector<std::string> values(request.count);
    for (std::size_t i = 0; i < sample.readings.size() && i < values.size(); ++i) {
        values[i] = device::csv_field(device::number_text(sample.readings[i].number));  // a string may hold a comma
    }
    fields.insert(fields.end(), values.begin(), values.end());
    return fmt::format("{}\n", fmt::join(fields, ","));
}

std::vector<std::string> raw_table_lines(const RawRequest& request, int unit, const RawSample& sample) {
    std::vector<std::string> lines;
    lines.push_back(fmt::format("loopwire monitor  {}  sample {}  (Ctrl-C to stop)", iso8601(sample.time, sample.utc), sample.index));
    std::string state = fmt::format("unit {}  {}  {}  {}  errors {}", unit, request.table->name, typing_text(request), sample.status, sample.errors);
    if (sample.status != "ok") state += "  " + sample.error.substr(0, 60);
    lines.push_back(state);
    lines.push_back(fmt::format("  {:>7} {:>24}  {}", "ADDRESS", "VALUE", "REGISTERS"));
    const auto addresses = value_addresses(request);
    for (std::size_t i = 0; i < addresses.size(); ++i) {
        if (i >= sample.readings.size()) {
            lines.push_back(fmt::format("  {:>7} \x1b[2m{:>24}\x1b[0m", addresses[i], "-"));
            continue;
        }
        const auto& reading = sample.readings[i];
        std::string hex;
        for (const auto word : reading.registers) hex += fmt::format(" {:04X}", word);
        lines.push_back(fmt::format("  {:>7} {:>24}  {}", reading.address, device::number_text(reading.number), hex.substr(1)));
    }
    return lines;
}

void poll_raw(device::Master& master, int unit, const RawRequest& request, unsigned per_request,
              const device::MonitorSettings& settings, MonitorFormat format, bool utc, RawOutput out, std::stop_token stop) {
    RawSampleWriter writer(request, unit, format, out.terminal, out.file);
    const auto range = register_range(static_cast<std::uint8_t>(unit), request, per_request);
    device::run_register_monitor(master, range, settings, [&](const device::RegisterSample& polled) {
        RawSample sample;
        sample.index = polled.index;
        sample.time = polled.time;
        sample.utc = utc;
        if (polled.error) {
            sample.status = status_of(*polled.error);
            sample.error = polled.error->message;
        } else {
            sample.readings = raw_readings(request, polled.words);
        }
        sample.errors = polled.errors;
        writer.write(sample);
    }, stop);
}

int run_raw_monitor(const MasterCommandOptions& master, const RawTypeOptions& typing, const std::vector<std::string>& arguments,
                    const device::MonitorSettings& settings, MonitorFormat format, const device::MonitorFileOptions& output) {
    if (arguments.empty() || arguments.size() > 3) {
        return report_error(make_error(ErrorKind::usage, "monitor takes --device DEVICE@UNIT [NAMES...] (by name), or --unit N "
                                                         "TABLE ADDRESS [COUNT] (raw registers, e.g. --unit 5 holding 100 4 --type float32)"));
    }
    auto request = parse_raw_request(arguments, typing);
    if (!request) return report_error(request.error());
    if (master.unit < 1 || master.unit > 247) {
        return report_error(make_error(ErrorKind::usage, "raw registers need --unit N, the unit id (1..247) to poll; or name a "
                                                         "profile with --device DEVICE@UNIT"));
    }
    auto per_request = per_request_on(master.link, *request);
    if (!per_request) return report_error(per_request.error());
    std::unique_ptr<device::FileSampleSink> file;
    if (!output.path.empty()) {
        auto opened = device::FileSampleSink::open(output, format, format == MonitorFormat::csv ? raw_csv_header(*request) : "");
        if (!opened) return report_error(opened.error());
        file = std::move(*opened);
    }
    StopSignal stop;  // before the master's threads start, so they inherit the blocked signals
    auto opened = master.open();
    if (!opened) return report_error(opened.error());
    poll_raw(**opened, master.unit, *request, *per_request, settings, format, output.time == TimeStyle::utc, RawOutput{stdout, file.get()},
             stop.token());
    return exit_ok;
}

}  // namespace loopwire::app
