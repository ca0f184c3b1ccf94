// loopwire write --link URL --unit N holding|coils ADDRESS VALUE... [--type T] [--word-order W]
//                [--byte-swap] [--scale F] [--base 0|1] [--multiple] [--json]
//                --link URL --device DEVICE@UNIT NAME=VALUE... [--json]
#include <algorithm>

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

struct WriteOptions {
    MasterCommandOptions master;
    RawTypeOptions typing;
    std::vector<std::string> arguments;  // TABLE ADDRESS VALUE..., or NAME=VALUE... with --device
    bool multiple = false;
};

codec::Request make_write(bool coils, bool multiple, std::uint16_t address, std::vector<std::uint16_t> values) {
    if (!multiple && values.size() == 1) {
        return coils ? codec::write_single_coil(address, values[0] != 0) : codec::write_single_register(address, values[0]);
    }
    return coils ? codec::write_multiple_coils(address, std::move(values))
                 : codec::write_multiple_registers(address, std::move(values));
}

// A value of several registers always goes with function 16: written one register at a time,
// the device would hold half of it between the two writes.
Result<void> write_range(device::Master& master, std::uint8_t unit, const RawWrite& write, bool multiple, unsigned per_request) {
    const bool coils = write.target.table->bits;
    const auto& words = write.words;
    for (std::size_t done = 0; done < words.size();) {
        const std::size_t chunk = std::min<std::size_t>(per_request, words.size() - done);
        std::vector<std::uint16_t> part(words.begin() + static_cast<long>(done), words.begin() + static_cast<long>(done + chunk));
        auto reply = master.execute(unit, make_write(coils, multiple || write.each > 1,
                                                     static_cast<std::uint16_t>(write.target.wire_address + done), std::move(part)));
        if (!reply) return reply.error();
        done += chunk;
    }
    return {};
}

void print_written(const WriteOptions& options, const RawWrite& write) {
    const auto& target = write.target;
    const bool broadcast = options.master.unit == 0;
    if (options.master.json) {
        nlohmann::ordered_json out{{"unit", options.master.unit}, {"table", target.table->name}, {"address", target.address}};
        if (target.typed) {
            describe_typing(target, out);
            nlohmann::ordered_json values = nlohmann::ordered_json::array();
            for (const auto& reading : raw_readings(target, write.words)) values.push_back(number_json(reading.number));
            out["values"] = values;
            out["registers"] = write.words;
        } else {
            if (target.base != 0) out["base"] = target.base;
            out["values"] = write.words;
        }
        out["broadcast"] = broadcast;
        fmt::print("{}\n", out.dump());
        return;
    }
    const std::string to = fmt::format("{} unit {}", broadcast ? "as broadcast, not answered, to every" : "to", options.master.unit);
    if (!target.typed) {
        fmt::print("wrote {} {} from address {} {}\n", write.words.size(), target.table->bits ? "coil(s)" : "register(s)",
                   target.address, to);
        return;
    }
    // What the registers now hold, read back through the same typing: a float32 shows the value
    // it could keep (12.3 stays 12.3; 16777217 becomes 16777216).
    std::string numbers;
    for (const auto& reading : raw_readings(target, write.words)) numbers += ", " + device::number_text(reading.number);
    fmt::print("wrote {} {} value(s) ({}; {} register(s)) from address {} {}\n", write.values.size(),
               device::raw_type_name(target.layout.type), numbers.substr(2), write.words.size(), target.address, to);
}

int run_raw_write(const WriteOptions& options) {
    auto write = parse_raw_write(options.arguments, options.typing);
    if (!write) return report_error(write.error());
    auto per_request = per_write_on(options.master.link, *write);
    if (!per_request) return report_error(per_request.error());
    auto master = options.master.open();
    if (!master) return report_error(master.error());
    auto written = write_range(**master, static_cast<std::uint8_t>(options.master.unit), *write, options.multiple, *per_request);
    if (!written) return report_error(written.error());
    print_written(options, *write);
    return exit_ok;
}

int run_write(WriteOptions options, const ProfileOptions& profiles) {
    if (!options.master.device.empty()) {
        if (options.typing.any_given()) return report_error(RawTypeOptions::not_with_names());
        auto registry = profiles.load();
        if (!registry) return report_error(registry.error());
        return run_device_write(*registry, options.master, options.arguments);
    }
    if (options.arguments.size() < 2) {
        return report_error(make_error(ErrorKind::usage, "write takes TABLE ADDRESS VALUE... or REFERENCE VALUE... (or --device "
                                                         "DEVICE@UNIT and NAME=VALUE pairs)"));
    }
    return run_raw_write(options);
}

}  // namespace

void add_write_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<WriteOptions>();
    auto* command = app.add_subcommand("write", "Write holding registers or coils");
    options->master.add_to(*command, true);
    options->master.add_identify_to(*command);
    command->add_option("arguments", options->arguments,
                        "TABLE ADDRESS VALUE...: holding|coils, the first address (0-based wire address, 1-based with --base 1, "
                        "or a reference such as 40001 in place of TABLE ADDRESS), values (registers 0..65535 or -32768..-1, decimal, "
                        "0x.. or ..h; with --type numbers of that type, each taking 1, 2 or 4 registers, or one text with --type string; "
                        "coils 0/1/on/off). With "
                        "--device: NAME=VALUE in engineering units or enum labels");
    options->typing.add_to(*command);
    command->add_flag("--multiple", options->multiple, "Use function 16/15 even for a single value (always for values of 2 or 4 registers)");
    command->footer(exit_code_help);
    command->callback([options, &exit_code, &profiles] {
        const JsonErrors json_errors(options->master.json);
        exit_code = run_write(*options, profiles);
    });
}

}  // namespace loopwire::app
