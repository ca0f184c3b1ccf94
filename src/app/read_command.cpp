// loopwire read --link URL --unit N holding|input|coils|discrete ADDRESS [COUNT] [--type T]
//               [--word-order big|little|ABCD|CDAB|BADC|DCBA] [--byte-swap] [--scale F] [--base 0|1]
//               [--format dec|hex|bin] [--json]
//               --link URL --unit N REFERENCE [COUNT] ... (40001: holding register 1)
//               --link URL --device DEVICE@UNIT NAME... [--json]
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/json_errors.hpp"
#include "app/device_read_write.hpp"
#include "app/master_options.hpp"
#include "app/raw_registers.hpp"

namespace loopwire::app {
namespace {

struct ReadOptions {
    MasterCommandOptions master;
    RawTypeOptions typing;
    std::vector<std::string> arguments;  // TABLE ADDRESS [COUNT], or names with --device
    std::string format;                  // empty: every column; dec, hex or bin: that one
};

// A plain word as --format shows it: "1234", "0x04D2" or "0000 0100 1101 0010".
std::string word_text(std::uint16_t word, const std::string& format) {
    if (format == "hex") return fmt::format("0x{:04X}", word);
    if (format == "bin") return fmt::format("{:04b} {:04b} {:04b} {:04b}", word >> 12, (word >> 8) & 0xF, (word >> 4) & 0xF, word & 0xF);
    return fmt::format("{}", word);
}

// Plain words: address, unsigned, hex and signed, as a register map lists them, under a header;
// or address and the one column --format names.
void print_words(const ReadOptions& options, const RawRequest& request, const std::vector<std::uint16_t>& values) {
    if (options.master.json) {
        nlohmann::ordered_json out{{"unit", options.master.unit}, {"table", request.table->name}, {"address", request.address}};
        if (request.base != 0) out["base"] = request.base;
        out["values"] = values;
        fmt::print("{}\n", out.dump());
        return;
    }
    if (request.table->bits) fmt::print("{:>7}  {}\n", "address", "value");
    else if (options.format.empty()) fmt::print("{:>7}  {:>8}  {:>6}  {:>6}\n", "address", "unsigned", "hex", "signed");
    else fmt::print("{:>7}  {}\n", "address", options.format == "bin" ? "binary" : options.format == "hex" ? "hex" : "decimal");
    for (std::size_t i = 0; i < values.size(); ++i) {
        const unsigned at = request.address + static_cast<unsigned>(i);
        if (request.table->bits) {
            fmt::print("{:7}  {}\n", at, values[i]);
        } else if (options.format.empty()) {
            fmt::print("{:7}  {:8}  0x{:04X}  {:6}\n", at, values[i], values[i], static_cast<std::int16_t>(values[i]));
        } else {
            fmt::print("{:7}  {}\n", at, word_text(values[i], options.format));
        }
    }
}

// Typed values: address, the number, and the registers it came from in hex.
void print_typed(const ReadOptions& options, const RawRequest& request, const std::vector<std::uint16_t>& words) {
    const auto readings = raw_readings(request, words);
    if (options.master.json) {
        nlohmann::ordered_json out{{"unit", options.master.unit}, {"table", request.table->name}, {"address", request.address}};
        describe_typing(request, out);
        nlohmann::ordered_json values = nlohmann::ordered_json::array();
        for (const auto& reading : readings) values.push_back(number_json(reading.number));
        out["values"] = values;
        out["registers"] = words;
        fmt::print("{}\n", out.dump());
        return;
    }
    fmt::print("{:>7}  {:>24}  {}\n", "address", device::raw_type_name(request.layout.type), "registers");
    for (const auto& reading : readings) {
        std::string hex;
        for (const auto word : reading.registers) hex += fmt::format(" {:04X}", word);
        fmt::print("{:7}  {:>24}  ({})\n", reading.address, device::number_text(reading.number), hex.substr(1));
    }
}

int run_raw_read(const ReadOptions& options) {
    auto request = parse_raw_request(options.arguments, options.typing);
    if (!request) return report_error(request.error());
    if (!options.format.empty()) {
        if (request->typed || request->table->bits || options.master.json) {
            return report_error(make_error(ErrorKind::usage, fmt::format(
                "--format {} shows plain registers as text; {} already says how the values are shown", options.format,
                options.master.json ? "--json" : request->typed ? "--type" : fmt::format("{} are single bits, which", request->table->name))));
        }
    }
    if (options.master.unit == 0) {
        return report_error(make_error(ErrorKind::usage, "unit 0 is broadcast, which nobody answers: reads need a unit id 1..255"));
    }
    auto per_request = per_request_on(options.master.link, *request);
    if (!per_request) return report_error(per_request.error());
    auto master = options.master.open();
    if (!master) return report_error(master.error());
    auto values = read_raw(**master, static_cast<std::uint8_t>(options.master.unit), *request, *per_request);
    if (!values) return report_error(values.error());
    if (request->typed) print_typed(options, *request, *values);
    else print_words(options, *request, *values);
    return exit_ok;
}

int run_read(const ReadOptions& options, const ProfileOptions& profiles) {
    if (!options.master.device.empty()) {
        if (options.typing.any_given()) return report_error(RawTypeOptions::not_with_names());
        if (!options.format.empty()) return report_error(make_error(ErrorKind::usage, "--format shows plain registers; a --device "
                                                                                      "profile shows its parameters in their units"));
        auto registry = profiles.load();
        if (!registry) return report_error(registry.error());
        return run_device_read(*registry, options.master, options.arguments);
    }
    if (options.arguments.empty() || options.arguments.size() > 3) {
        return report_error(make_error(ErrorKind::usage, "read takes TABLE ADDRESS [COUNT] or REFERENCE [COUNT] (or --device "
                                                         "DEVICE@UNIT and parameter names)"));
    }
    return run_raw_read(options);
}

}  // namespace

void add_read_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<ReadOptions>();
    auto* command = app.add_subcommand("read", "Read registers, coils or discrete inputs from a device");
    options->master.add_to(*command, true);
    options->master.add_identify_to(*command);
    command->add_option("arguments", options->arguments,
                        std::string(raw_count_help) + ". With --device: parameter names, mnemonics, groups or all");
    options->typing.add_to(*command);
    command->add_option("--format", options->format, "Show plain registers in one column: dec, hex (0x04D2) or bin "
                                                     "(0000 0100 1101 0010); default: unsigned, hex and signed")
        ->check(CLI::IsMember({"dec", "hex", "bin"}));
    command->footer(exit_code_help);
    command->callback([options, &exit_code, &profiles] {
        const JsonErrors json_errors(options->master.json);
        exit_code = run_read(*options, profiles);
    });
}

}  // namespace loopwire::app
