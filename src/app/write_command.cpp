// loopwire write --link URL --unit N holding|coils ADDRESS VALUE... [--multiple] [--json]
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

namespace loopwire::app {
namespace {

struct WriteOptions {
    MasterCommandOptions master;
    std::vector<std::string> arguments;  // TABLE ADDRESS VALUE..., or NAME=VALUE... with --device
    std::string table;
    std::string address;
    std::vector<std::string> values;
    bool multiple = false;
};

Result<std::uint16_t> parse_coil(const std::string& text) {
    std::string lower = text;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (lower == "1" || lower == "on" || lower == "true") return std::uint16_t{1};
    if (lower == "0" || lower == "off" || lower == "false") return std::uint16_t{0};
    return make_error(ErrorKind::usage, fmt::format("coil value '{}' must be 0, 1, on, off, true or false", text));
}

// Registers take unsigned 0..65535 or signed -32768..-1 (sent as two's complement).
Result<std::vector<std::uint16_t>> parse_values(const WriteOptions& options, bool coils) {
    std::vector<std::uint16_t> values;
    for (const auto& text : options.values) {
        if (coils) {
            auto coil = parse_coil(text);
            if (!coil) return coil.error();
            values.push_back(*coil);
            continue;
        }
        auto value = parse_integer(text, -32768, 65535, "register value");
        if (!value) return value.error();
        values.push_back(static_cast<std::uint16_t>(*value));
    }
    return values;
}

codec::Request make_write(bool coils, bool multiple, std::uint16_t address, std::vector<std::uint16_t> values) {
    if (!multiple && values.size() == 1) {
        return coils ? codec::write_single_coil(address, values[0] != 0) : codec::write_single_register(address, values[0]);
    }
    return coils ? codec::write_multiple_coils(address, std::move(values))
                 : codec::write_multiple_registers(address, std::move(values));
}

Result<void> write_range(session::Master& master, std::uint8_t unit, bool coils, bool multiple,
                         std::uint16_t address, const std::vector<std::uint16_t>& values, std::size_t per_request) {
    for (std::size_t done = 0; done < values.size();) {
        const std::size_t chunk = std::min(per_request, values.size() - done);
        std::vector<std::uint16_t> part(values.begin() + static_cast<long>(done), values.begin() + static_cast<long>(done + chunk));
        auto reply = master.execute(unit, make_write(coils, multiple, static_cast<std::uint16_t>(address + done), std::move(part)));
        if (!reply) return reply.error();
        done += chunk;
    }
    return {};
}

int run_raw_write(const WriteOptions& options) {
    const bool coils = options.table == "coils";
    if (!coils && options.table != "holding") {
        return report_error(make_error(ErrorKind::usage, fmt::format("cannot write table '{}': choose holding or coils", options.table)));
    }
    auto address = parse_integer(options.address, 0, 0xFFFF, "address");
    if (!address) return report_error(address.error());
    auto values = parse_values(options, coils);
    if (!values) return report_error(values.error());
    if (static_cast<std::size_t>(*address) + values->size() > 0x10000) {  // address is 0..65535 here
        return report_error(make_error(ErrorKind::usage, fmt::format("{} values from address {} run past the last address 65535", values->size(), *address)));
    }
    auto url = transport::parse_link_url(options.master.link);
    if (!url) return report_error(url.error());
    auto master = options.master.open();
    if (!master) return report_error(master.error());
    std::size_t per_request = coils ? codec::max_write_bits : codec::max_write_registers;
    if (url->framing == transport::Framing::linking) per_request = 1;
    auto written = write_range(**master, static_cast<std::uint8_t>(options.master.unit), coils, options.multiple,
                               static_cast<std::uint16_t>(*address), *values, per_request);
    if (!written) return report_error(written.error());
    if (options.master.json) {
        nlohmann::ordered_json out{{"unit", options.master.unit}, {"table", options.table}, {"address", *address},
                           {"values", *values}, {"broadcast", options.master.unit == 0}};
        fmt::print("{}\n", out.dump());
    } else {
        fmt::print("wrote {} {} from address {} {} unit {}\n", values->size(), coils ? "coil(s)" : "register(s)", *address,
                   options.master.unit == 0 ? "as broadcast, not answered, to every" : "to", options.master.unit);
    }
    return exit_ok;
}

int run_write(WriteOptions options, const ProfileOptions& profiles) {
    if (!options.master.device.empty()) {
        auto registry = profiles.load();
        if (!registry) return report_error(registry.error());
        return run_device_write(*registry, options.master, options.arguments);
    }
    if (options.arguments.size() < 3) {
        return report_error(make_error(ErrorKind::usage, "write takes TABLE ADDRESS VALUE... (or --device DEVICE@UNIT and NAME=VALUE pairs)"));
    }
    options.table = options.arguments[0];
    options.address = options.arguments[1];
    options.values.assign(options.arguments.begin() + 2, options.arguments.end());
    return run_raw_write(options);
}

}  // namespace

void add_write_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<WriteOptions>();
    auto* command = app.add_subcommand("write", "Write holding registers or coils");
    options->master.add_to(*command, true);
    command->add_option("arguments", options->arguments,
                        "TABLE ADDRESS VALUE...: holding|coils, first 0-based wire address, values (registers 0..65535 or "
                        "-32768..-1, decimal, 0x.. or ..h; coils 0/1/on/off). With --device: NAME=VALUE in engineering units or enum labels");
    command->add_flag("--multiple", options->multiple, "Use function 16/15 even for a single value");
    command->footer(exit_code_help);
    command->callback([options, &exit_code, &profiles] {
        const JsonErrors json_errors(options->master.json);
        exit_code = run_write(*options, profiles);
    });
}

}  // namespace loopwire::app
