// loopwire read --link URL --unit N holding|input|coils|discrete ADDRESS COUNT [--json]
//               --link URL --device DEVICE@UNIT NAME... [--json]
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/device_read_write.hpp"
#include "app/master_options.hpp"

namespace loopwire::app {
namespace {

struct ReadTable {
    const char* name;
    codec::FunctionCode function;
    unsigned most_per_request;  // Modbus application protocol V1.1b3, 6.1-6.4
    bool bits;
};

constexpr ReadTable read_tables[] = {
    {"holding", codec::FunctionCode::read_holding_registers, codec::max_read_registers, false},
    {"input", codec::FunctionCode::read_input_registers, codec::max_read_registers, false},
    {"coils", codec::FunctionCode::read_coils, codec::max_read_bits, true},
    {"discrete", codec::FunctionCode::read_discrete_inputs, codec::max_read_bits, true},
};

const ReadTable* find_table(const std::string& name) {
    for (const auto& table : read_tables) {
        if (name == table.name) return &table;
    }
    return nullptr;
}

struct ReadOptions {
    MasterCommandOptions master;
    std::vector<std::string> arguments;  // TABLE ADDRESS [COUNT], or names with --device
    std::string table;
    std::string address;
    std::string count = "1";
};

// Reads [address, address+count) in as few requests as the protocol allows (one register per
// request on a Linking link).
Result<std::vector<std::uint16_t>> read_range(session::Master& master, std::uint8_t unit, const ReadTable& table,
                                              std::uint16_t address, unsigned count, unsigned per_request) {
    std::vector<std::uint16_t> values;
    while (values.size() < count) {
        const auto chunk = static_cast<std::uint16_t>(std::min<std::size_t>(per_request, count - values.size()));
        const auto at = static_cast<std::uint16_t>(address + values.size());
        auto reply = master.execute(unit, codec::read_request(table.function, at, chunk));
        if (!reply) return reply.error();
        values.insert(values.end(), reply->values.begin(), reply->values.end());
    }
    return values;
}

void print_values(const ReadOptions& options, const ReadTable& table, std::uint16_t address,
                  const std::vector<std::uint16_t>& values) {
    if (options.master.json) {
        nlohmann::ordered_json out{{"unit", options.master.unit}, {"table", table.name}, {"address", address}, {"values", values}};
        fmt::print("{}\n", out.dump());
        return;
    }
    for (std::size_t i = 0; i < values.size(); ++i) {
        const unsigned at = address + static_cast<unsigned>(i);
        if (table.bits) {
            fmt::print("{:5}  {}\n", at, values[i]);
        } else {
            fmt::print("{:5}  {:5}  0x{:04X}  {:6}\n", at, values[i], values[i], static_cast<std::int16_t>(values[i]));
        }
    }
}

int run_raw_read(const ReadOptions& options) {
    const ReadTable* table = find_table(options.table);
    if (!table) {
        return report_error(make_error(ErrorKind::usage, fmt::format("unknown table '{}': choose holding, input, coils or discrete", options.table)));
    }
    auto address = parse_integer(options.address, 0, 0xFFFF, "address");
    if (!address) return report_error(address.error());
    auto count = parse_integer(options.count, 1, 0x10000 - *address, "count");
    if (!count) return report_error(count.error());
    if (options.master.unit == 0) {
        return report_error(make_error(ErrorKind::usage, "unit 0 is broadcast, which nobody answers: reads need a unit id 1..255"));
    }
    auto url = transport::parse_link_url(options.master.link);
    if (!url) return report_error(url.error());
    auto master = options.master.open();
    if (!master) return report_error(master.error());
    const unsigned per_request = url->framing == transport::Framing::linking ? 1u : table->most_per_request;
    auto values = read_range(**master, static_cast<std::uint8_t>(options.master.unit), *table,
                             static_cast<std::uint16_t>(*address), static_cast<unsigned>(*count), per_request);
    if (!values) return report_error(values.error());
    print_values(options, *table, static_cast<std::uint16_t>(*address), *values);
    return exit_ok;
}

int run_read(ReadOptions options, const ProfileOptions& profiles) {
    if (!options.master.device.empty()) {
        auto registry = profiles.load();
        if (!registry) return report_error(registry.error());
        return run_device_read(*registry, options.master, options.arguments);
    }
    if (options.arguments.size() < 2 || options.arguments.size() > 3) {
        return report_error(make_error(ErrorKind::usage, "read takes TABLE ADDRESS [COUNT] (or --device DEVICE@UNIT and parameter names)"));
    }
    options.table = options.arguments[0];
    options.address = options.arguments[1];
    if (options.arguments.size() == 3) options.count = options.arguments[2];
    return run_raw_read(options);
}

}  // namespace

void add_read_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles) {
    auto options = std::make_shared<ReadOptions>();
    auto* command = app.add_subcommand("read", "Read registers, coils or discrete inputs from a device");
    options->master.add_to(*command, true);
    command->add_option("arguments", options->arguments,
                        "TABLE ADDRESS [COUNT]: holding|input|coils|discrete, first 0-based wire address (decimal, 0x.. or ..h), "
                        "how many (split into several requests where needed). With --device: parameter names, mnemonics, groups or all");
    command->footer(exit_code_help);
    command->callback([options, &exit_code, &profiles] { exit_code = run_read(*options, profiles); });
}

}  // namespace loopwire::app
