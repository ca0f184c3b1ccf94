#include "app/raw_registers.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "transport/link_url.hpp"

namespace loopwire::app {
namespace {

constexpr ReadTable read_tables[] = {
    {"holding", codec::FunctionCode::read_holding_registers, codec::max_read_registers, false},
    {"input", codec::FunctionCode::read_input_registers, codec::max_read_registers, false},
    {"coils", codec::FunctionCode::read_coils, codec::max_read_bits, true},
    {"discrete", codec::FunctionCode::read_discrete_inputs, codec::max_read_bits, true},
};

constexpr unsigned address_space = 0x10000;

bool typing_given(const RawTypeOptions& options) {
    return !options.type.empty() || !options.word_order.empty() || options.byte_swap || !options.scale.empty();
}

Result<device::RawLayout> layout_of(const RawTypeOptions& options) {
    device::RawLayout layout;
    if (!options.type.empty()) {
        auto type = device::parse_raw_type(options.type);
        if (!type) return type.error();
        layout.type = *type;
    }
    if (!options.word_order.empty()) {
        auto order = device::parse_word_order(options.word_order);
        if (!order) return order.error();
        layout.word_order = *order;
    }
    layout.byte_swap = options.byte_swap;
    return layout;
}

// ADDRESS in the --base numbering, to the wire address.
Result<unsigned> wire_address_of(const std::string& text, int base) {
    auto address = parse_integer(text, 0, static_cast<long long>(address_space) - 1 + base, "address");
    if (!address) return address.error();
    if (*address < base) {
        return make_error(ErrorKind::usage, fmt::format("address {} does not exist with --base 1: addresses start at 1 "
                                                        "(drop --base for 0-based wire addresses)", text));
    }
    return static_cast<unsigned>(*address - base);
}

}  // namespace

const char* const raw_count_help =
    "TABLE ADDRESS [COUNT]: holding|input|coils|discrete, the first address (0-based wire address, or 1-based with "
    "--base 1; decimal, 0x.. or ..h) and how many values to read (default 1; with --type a value takes 1, 2 or 4 "
    "registers: holding 100 2 --type float32 reads registers 100-103)";

const ReadTable* find_read_table(const std::string& name) {
    for (const auto& table : read_tables) {
        if (name == table.name) return &table;
    }
    return nullptr;
}

void RawTypeOptions::add_to(CLI::App& command) {
    command.add_option("--type", type,
                       "What the registers hold: int16, uint16, int32, uint32, float32 (IEEE 754, 2 registers) or float64 "
                       "(4 registers); COUNT counts values of this type");
    command.add_option("--word-order", word_order,
                       "Register order of 32/64-bit values: big (most significant register first, the Modbus convention; "
                       "default) or little");
    command.add_flag("--byte-swap", byte_swap, "Swap the two bytes of every register before decoding");
    command.add_option("--scale", scale, "Multiply every value by this factor: 0.1, 10, ...");
    command.add_option("--base", base, "Address numbering: 0 (wire addresses, default) or 1 (the first register is 1)")
        ->check(CLI::IsMember({0, 1}));
}

bool RawTypeOptions::any_given() const { return typing_given(*this) || base != 0; }

Error RawTypeOptions::not_with_names() {
    return make_error(ErrorKind::usage, "--type, --word-order, --byte-swap, --scale and --base apply to registers read as TABLE "
                                        "ADDRESS [COUNT]; a --device profile already says how its parameters are encoded");
}

Result<RawRequest> parse_raw_request(const std::vector<std::string>& arguments, const RawTypeOptions& options) {
    RawRequest request;
    request.table = find_read_table(arguments.at(0));
    if (!request.table) {
        return make_error(ErrorKind::usage, fmt::format("unknown table '{}': choose holding, input, coils or discrete", arguments[0]));
    }
    request.typed = typing_given(options);
    if (request.typed && request.table->bits) {
        return make_error(ErrorKind::usage, fmt::format("--type, --word-order, --byte-swap and --scale apply to registers (holding, "
                                                        "input); {} are single bits", request.table->name));
    }
    auto layout = layout_of(options);
    if (!layout) return layout.error();
    request.layout = *layout;
    if (!options.scale.empty()) {
        auto scale = device::parse_scale(options.scale);
        if (!scale) return scale.error();
        request.scale = *scale;
    }
    request.base = options.base;
    auto wire = wire_address_of(arguments.at(1), options.base);
    if (!wire) return wire.error();
    request.wire_address = static_cast<std::uint16_t>(*wire);
    request.address = *wire + static_cast<unsigned>(options.base);
    auto count = parse_integer(arguments.size() > 2 ? arguments[2] : "1", 1, address_space, "count");
    if (!count) return count.error();
    request.count = static_cast<unsigned>(*count);
    const unsigned each = device::registers_per_value(request.layout.type);
    const unsigned available = address_space - *wire;
    if (static_cast<unsigned long long>(request.count) * each > available) {
        const unsigned last = address_space - 1 + static_cast<unsigned>(options.base);
        return make_error(ErrorKind::usage,
                          fmt::format("{} {} value{} from {} {} would need {} registers, but only {} remain up to the last "
                                      "address {}", request.count, device::raw_type_name(request.layout.type),
                                      request.count == 1 ? "" : "s", request.table->name, request.address,
                                      static_cast<unsigned long long>(request.count) * each, available, last));
    }
    request.registers = request.count * each;
    return request;
}

Result<unsigned> per_request_on(const std::string& link, const RawRequest& request) {
    auto url = transport::parse_link_url(link);
    if (!url) return url.error();
    return url->framing == transport::Framing::linking ? 1u : request.table->most_per_request;
}

Result<std::vector<std::uint16_t>> read_raw(session::Master& master, std::uint8_t unit, const RawRequest& request,
                                            unsigned per_request) {
    std::vector<std::uint16_t> values;
    while (values.size() < request.registers) {
        const auto chunk = static_cast<std::uint16_t>(std::min<std::size_t>(per_request, request.registers - values.size()));
        const auto at = static_cast<std::uint16_t>(request.wire_address + values.size());
        auto reply = master.execute(unit, codec::read_request(request.table->function, at, chunk));
        if (!reply) return reply.error();
        values.insert(values.end(), reply->values.begin(), reply->values.end());
    }
    return values;
}

std::vector<RawReading> raw_readings(const RawRequest& request, const std::vector<std::uint16_t>& words) {
    std::vector<RawReading> readings;
    const unsigned each = device::registers_per_value(request.layout.type);
    for (std::size_t at = 0; at + each <= words.size(); at += each) {
        RawReading reading;
        reading.address = request.address + static_cast<unsigned>(at);
        reading.registers.assign(words.begin() + static_cast<std::ptrdiff_t>(at), words.begin() + static_cast<std::ptrdiff_t>(at + each));
        reading.number = device::decode_value(reading.registers, request.layout);
        if (request.scale) reading.number = device::scaled(reading.number, *request.scale);
        readings.push_back(std::move(reading));
    }
    return readings;
}

nlohmann::ordered_json number_json(const device::RawNumber& number) {
    if (const auto* integer = std::get_if<std::int64_t>(&number)) return *integer;
    const double value = std::get<double>(number);
    if (!std::isfinite(value)) return nullptr;
    return value;
}

void describe_typing(const RawRequest& request, nlohmann::ordered_json& out) {
    out["type"] = std::string(device::raw_type_name(request.layout.type));
    out["word_order"] = std::string(device::word_order_name(request.layout.word_order));
    out["byte_swap"] = request.layout.byte_swap;
    out["scale"] = request.scale ? nlohmann::ordered_json(device::scaled(std::int64_t{1}, *request.scale)) : nlohmann::ordered_json(nullptr);
    if (request.base != 0) out["base"] = request.base;
}

}  // namespace loopwire::app
