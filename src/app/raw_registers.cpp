#include "app/raw_registers.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "client/register_monitor.hpp"

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
    layout.byte_swap = options.byte_swap;
    if (!options.word_order.empty()) {
        auto order = device::parse_word_order(options.word_order);
        if (!order) return order.error();
        layout.word_order = order->order;
        if (order->byte_swap) {
            if (options.byte_swap) {
                return make_error(ErrorKind::usage, fmt::format("--word-order {} already says how the bytes are ordered: drop "
                                                                "--byte-swap, or give big or little with it", options.word_order));
            }
            layout.byte_swap = *order->byte_swap;
        }
    }
    return layout;
}

// A reference address names its table by its first digit, as Modbus Poll and many manuals write
// them: 4xxxx holding, 3xxxx input, 1xxxx discrete, 0xxxx coils, numbered from 1 (40001 is
// holding register 1, wire address 0). Five digits reach 9999 registers, six reach 65536.
struct Reference {
    const ReadTable* table = nullptr;
    std::uint16_t wire = 0;
    unsigned last_wire = 0;  // the last wire address references of this width reach
};

const ReadTable* table_of_prefix(char prefix) {
    switch (prefix) {
        case '4': return find_read_table("holding");
        case '3': return find_read_table("input");
        case '1': return find_read_table("discrete");
        case '0': return find_read_table("coils");
        default: return nullptr;
    }
}

std::optional<Reference> reference_of(const std::string& text) {
    if ((text.size() != 5 && text.size() != 6) || !std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; })) {
        return std::nullopt;
    }
    const ReadTable* table = table_of_prefix(text.front());
    const unsigned number = static_cast<unsigned>(std::stoul(text.substr(1)));
    const unsigned last = text.size() == 5 ? 9999 : address_space;
    if (!table || number < 1 || number > last) return std::nullopt;
    return Reference{table, static_cast<std::uint16_t>(number - 1), last - 1};
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

// TABLE ADDRESS, or a reference alone: the request's table and addresses; how many arguments
// they took.
Result<std::size_t> parse_target(const std::vector<std::string>& arguments, int base, RawRequest& request) {
    if (arguments.empty()) return make_error(ErrorKind::usage, "give TABLE ADDRESS (holding 100) or a reference address (40101)");
    const auto reference = reference_of(arguments[0]);
    if (reference) {  // a reference alone: its table, numbered from 1
        request.table = reference->table;
        request.base = 1;
        request.wire_address = reference->wire;
        request.address = static_cast<unsigned>(std::stoul(arguments[0]));
        request.last_wire = reference->last_wire;
        return std::size_t{1};
    }
    request.table = find_read_table(arguments[0]);
    if (!request.table) {
        return make_error(ErrorKind::usage, fmt::format("unknown table '{}': choose holding, input, coils or discrete, or give a "
                                                        "reference address (40001 is holding register 1)", arguments[0]));
    }
    if (arguments.size() < 2) return make_error(ErrorKind::usage, fmt::format("give the first address after {}", arguments[0]));
    request.base = base;
    // With --base 1, a reference of the table's own range is a reference: holding 40001 is holding
    // register 1, as a Modbus Poll user means it; --base 0 reaches wire address 40000.
    const auto typed_reference = base == 1 ? reference_of(arguments[1]) : std::nullopt;
    if (typed_reference && typed_reference->table == request.table && arguments[1].front() != '0') {
        request.wire_address = typed_reference->wire;
        request.address = static_cast<unsigned>(std::stoul(arguments[1]));
        request.last_wire = typed_reference->last_wire;
        return std::size_t{2};
    }
    auto wire = wire_address_of(arguments[1], base);
    if (!wire) return wire.error();
    request.wire_address = static_cast<std::uint16_t>(*wire);
    request.address = *wire + static_cast<unsigned>(base);
    request.last_wire = address_space - 1;
    return std::size_t{2};
}

Result<void> parse_typing(const RawTypeOptions& options, RawRequest& request) {
    request.typed = typing_given(options);
    if (request.typed && request.table->bits) {
        return make_error(ErrorKind::usage, fmt::format("--type, --word-order, --byte-swap and --scale apply to registers (holding, "
                                                        "input); {} are single bits", request.table->name));
    }
    auto layout = layout_of(options);
    if (!layout) return layout.error();
    request.layout = *layout;
    if (request.layout.type == device::RawType::string && !options.scale.empty()) {
        return make_error(ErrorKind::usage, "--scale multiplies numbers; a string is text: drop --scale or choose a number type");
    }
    if (!options.scale.empty()) {
        auto scale = device::parse_scale(options.scale);
        if (!scale) return scale.error();
        request.scale = *scale;
    }
    return {};
}

// The request's first address shown for wire address `wire`.
unsigned shown_address(const RawRequest& request, unsigned wire) { return request.address + (wire - request.wire_address); }

Result<void> check_room(const RawRequest& request, unsigned long long registers, const std::string& what) {
    const unsigned available = request.last_wire + 1 - request.wire_address;
    if (registers <= available) return {};
    return make_error(ErrorKind::usage, fmt::format("{} from {} {} would need {} registers, but only {} remain up to the last address {}",
                                                    what, request.table->name, request.address, registers, available,
                                                    shown_address(request, request.last_wire)));
}

Result<std::uint16_t> parse_coil(const std::string& text) {
    std::string lower = text;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (lower == "1" || lower == "on" || lower == "true") return std::uint16_t{1};
    if (lower == "0" || lower == "off" || lower == "false") return std::uint16_t{0};
    return make_error(ErrorKind::usage, fmt::format("coil value '{}' must be 0, 1, on, off, true or false", text));
}

Result<std::vector<std::uint16_t>> coil_words(const std::vector<std::string>& values) {
    std::vector<std::uint16_t> words;
    for (const auto& text : values) {
        auto coil = parse_coil(text);
        if (!coil) return coil.error();
        words.push_back(*coil);
    }
    return words;
}

// Untyped, a register takes 0..65535 or -32768..-1 (sent as two's complement); typed, each value
// becomes the registers of its type (client/raw_values.hpp).
Result<std::vector<std::uint16_t>> register_words(const std::vector<std::string>& values, const RawRequest& request) {
    std::vector<std::uint16_t> words;
    for (const auto& text : values) {
        if (!request.typed) {
            auto value = parse_integer(text, -32768, 65535, "register value");
            if (!value) return value.error();
            words.push_back(static_cast<std::uint16_t>(*value));
            continue;
        }
        auto encoded = device::encode_value(text, request.layout, request.scale);
        if (!encoded) return encoded.error();
        words.insert(words.end(), encoded->begin(), encoded->end());
    }
    return words;
}

}  // namespace

const char* const raw_count_help =
    "TABLE ADDRESS [COUNT]: holding|input|coils|discrete, the first address (0-based wire address, or 1-based with "
    "--base 1; decimal, 0x.. or ..h) and how many values to read (default 1; with --type a value takes 1, 2 or 4 "
    "registers: holding 100 2 --type float32 reads registers 100-103; a string's COUNT counts its registers, two "
    "characters each)";

const ReadTable* find_read_table(const std::string& name) {
    for (const auto& table : read_tables) {
        if (name == table.name) return &table;
    }
    return nullptr;
}

void RawTypeOptions::add_to(CLI::App& command) {
    command.add_option("--type", type,
                       "What the registers hold: int16, uint16, int32, uint32, float32 (IEEE 754, 2 registers), float64 "
                       "(4 registers), or string (ASCII, two characters a register, the first in the high byte; with "
                       "--byte-swap, BADC or DCBA the low byte; padded with NUL, read up to the first NUL); COUNT counts "
                       "values of this type (registers for a string)")
        ->type_name("TYPE:{int16,uint16,int32,uint32,float32,float64,string}");  // the choices, for completion
    command.add_option("--word-order", word_order,
                       "Register order of 32/64-bit values: big (most significant register first, the Modbus convention; "
                       "default) or little; or the byte order as Modbus tools name it: ABCD (big), CDAB (little), BADC (big, "
                       "bytes swapped), DCBA (little, bytes swapped)")
        ->type_name("ORDER:{big,little,ABCD,CDAB,BADC,DCBA}");
    command.add_flag("--byte-swap", byte_swap, "Swap the two bytes of every register");
    command.add_option("--scale", scale, "The factor between register and value: 0.1, 10, ... (values shown and written are "
                                         "the register times the factor)");
    command.add_option("--base", base, "Address numbering: 0 (wire addresses, default) or 1 (the first register is 1; a "
                                       "reference such as 40001 is holding register 1)")
        ->check(CLI::IsMember({0, 1}));
}

bool RawTypeOptions::any_given() const { return typing_given(*this) || base != 0; }

Error RawTypeOptions::not_with_names() {
    return make_error(ErrorKind::usage, "--type, --word-order, --byte-swap, --scale and --base apply to registers given as TABLE "
                                        "ADDRESS; a --device profile already says how its parameters are encoded");
}

Result<RawRequest> parse_raw_request(const std::vector<std::string>& arguments, const RawTypeOptions& options) {
    RawRequest request;
    auto taken = parse_target(arguments, options.base, request);
    if (!taken) return taken.error();
    if (arguments.size() > *taken + 1) {
        return make_error(ErrorKind::usage, fmt::format("'{}' is one argument too many: give TABLE ADDRESS [COUNT] or REFERENCE "
                                                        "[COUNT]", arguments[*taken + 1]));
    }
    auto typing = parse_typing(options, request);
    if (!typing) return typing.error();
    auto count = parse_integer(arguments.size() > *taken ? arguments[*taken] : "1", 1, address_space, "count");
    if (!count) return count.error();
    request.count = static_cast<unsigned>(*count);
    if (request.layout.type == device::RawType::string) {
        // COUNT counts the string's registers, two characters each: one value of them all.
        auto fits = check_room(request, request.count, fmt::format("a string of {} register{}", request.count, request.count == 1 ? "" : "s"));
        if (!fits) return fits.error();
        request.registers = request.count;
        request.count = 1;
        return request;
    }
    const unsigned each = device::registers_per_value(request.layout.type);
    auto fits = check_room(request, static_cast<unsigned long long>(request.count) * each,
                           fmt::format("{} {} value{}", request.count, device::raw_type_name(request.layout.type),
                                       request.count == 1 ? "" : "s"));
    if (!fits) return fits.error();
    request.registers = request.count * each;
    return request;
}

Result<RawWrite> parse_raw_write(const std::vector<std::string>& arguments, const RawTypeOptions& options) {
    RawWrite write;
    auto taken = parse_target(arguments, options.base, write.target);
    if (!taken) return taken.error();
    const auto& table = *write.target.table;
    if (table.function != codec::FunctionCode::read_holding_registers && table.function != codec::FunctionCode::read_coils) {
        return make_error(ErrorKind::usage, fmt::format("cannot write {}: {} are read-only; write holding or coils", table.name, table.name));
    }
    write.values.assign(arguments.begin() + static_cast<std::ptrdiff_t>(*taken), arguments.end());
    if (write.values.empty()) return make_error(ErrorKind::usage, "give the value(s) to write after the address");
    auto typing = parse_typing(options, write.target);
    if (!typing) return typing.error();
    const bool text = write.target.layout.type == device::RawType::string;
    if (text && write.values.size() != 1) {
        return make_error(ErrorKind::usage, fmt::format("--type string writes one text, {} were given: quote a text with spaces "
                                                        "(\"AB 12\")", write.values.size()));
    }
    auto words = table.bits ? coil_words(write.values) : register_words(write.values, write.target);
    if (!words) return words.error();
    write.words = std::move(*words);
    if (text && write.words.size() > codec::max_write_registers) {
        return make_error(ErrorKind::usage, fmt::format("'{}' is too long: its {} characters take {} registers, and one write "
                                                        "carries at most {} ({} characters)", write.values.front(),
                                                        write.values.front().size(), write.words.size(), codec::max_write_registers,
                                                        2 * codec::max_write_registers));
    }
    const unsigned each = text ? static_cast<unsigned>(write.words.size()) : device::registers_per_value(write.target.layout.type);
    write.target.count = static_cast<unsigned>(write.values.size());
    write.target.registers = static_cast<unsigned>(write.words.size());
    auto fits = check_room(write.target, write.words.size(),
                           fmt::format("{} value{}", write.values.size(), write.values.size() == 1 ? "" : "s"));
    if (!fits) return fits.error();
    write.each = each;
    return write;
}

Result<unsigned> per_request_on(const std::string& link, const RawRequest& request) {
    auto linking = device::is_linking_link(link);
    if (!linking) return linking.error();
    return *linking ? 1u : request.table->most_per_request;
}

Result<std::vector<std::uint16_t>> read_raw(device::Master& master, std::uint8_t unit, const RawRequest& request,
                                            unsigned per_request) {
    return device::read_registers(master, register_range(unit, request, per_request));
}

device::RegisterRange register_range(std::uint8_t unit, const RawRequest& request, unsigned per_request) {
    return device::RegisterRange{unit, request.table->function, request.wire_address, request.registers, per_request};
}

Result<unsigned> per_write_on(const std::string& link, const RawWrite& write) {
    auto linking = device::is_linking_link(link);
    if (!linking) return linking.error();
    const unsigned most = write.target.table->bits ? codec::max_write_bits : codec::max_write_registers;
    if (!*linking) return most - most % write.each;  // a value never split between two requests
    if (write.each > 1) {
        return make_error(ErrorKind::usage, fmt::format("a {} takes {} registers, and a Linking link writes one register per message: "
                                                        "the device would hold half a value between them; write the registers one "
                                                        "by one without --type if that is meant",
                                                        device::raw_type_name(write.target.layout.type), write.each));
    }
    return 1u;
}

std::vector<RawReading> raw_readings(const RawRequest& request, const std::vector<std::uint16_t>& words) {
    std::vector<RawReading> readings;
    const bool text = request.layout.type == device::RawType::string;
    const unsigned each = text ? std::max(request.registers, 1u) : device::registers_per_value(request.layout.type);
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
    if (const auto* text = std::get_if<std::string>(&number)) return *text;
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
