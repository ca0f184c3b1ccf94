#include "codec/table.hpp"

#include <array>

namespace loopwire::codec {
namespace {

struct TableFacts {
    Table table;
    std::string_view name;
    FunctionCode read;
};

constexpr std::array<TableFacts, 4> tables{{
    {Table::coils, "coils", FunctionCode::read_coils},
    {Table::discrete_inputs, "discrete", FunctionCode::read_discrete_inputs},
    {Table::holding_registers, "holding", FunctionCode::read_holding_registers},
    {Table::input_registers, "input", FunctionCode::read_input_registers},
}};

// Indexed by the enum: each entry sits at its table's value.
constexpr bool in_enum_order() {
    for (std::size_t i = 0; i < tables.size(); ++i) {
        if (static_cast<std::size_t>(tables[i].table) != i) return false;
    }
    return true;
}
static_assert(in_enum_order());

const TableFacts& facts(Table table) { return tables.at(static_cast<std::size_t>(table)); }

}  // namespace

std::string_view table_name(Table table) { return facts(table).name; }

std::optional<Table> table_named(std::string_view name) {
    for (const auto& entry : tables) {
        if (entry.name == name) return entry.table;
    }
    return std::nullopt;
}

FunctionCode read_function(Table table) { return facts(table).read; }

std::optional<Table> table_read_by(std::uint8_t function) {
    for (const auto& entry : tables) {
        if (static_cast<std::uint8_t>(entry.read) == function) return entry.table;
    }
    return std::nullopt;
}

// Modbus application protocol V1.1b3, 6.1-6.4: function, starting address, quantity.
std::optional<DataSpan> read_span(ByteView request_pdu) {
    if (request_pdu.size() < 5) return std::nullopt;
    static constexpr std::array<Table, 4> tables{Table::coils, Table::discrete_inputs, Table::holding_registers, Table::input_registers};
    const std::uint8_t function = request_pdu[0];
    if (function < 1 || function > 4) return std::nullopt;
    return DataSpan{tables[function - 1u], read_be16(request_pdu, 1), read_be16(request_pdu, 3)};
}

// 6.5, 6.6, 6.11, 6.12: address, then value or quantity; 6.16 (22): one register; 6.17 (23):
// read address and quantity, then the write address and quantity.
std::optional<DataSpan> written_span(ByteView request_pdu) {
    if (request_pdu.size() < 5) return std::nullopt;
    const std::uint16_t address = read_be16(request_pdu, 1);
    switch (request_pdu[0]) {
        case 5: return DataSpan{Table::coils, address, 1};
        case 6: return DataSpan{Table::holding_registers, address, 1};
        case 15: return DataSpan{Table::coils, address, read_be16(request_pdu, 3)};
        case 16: return DataSpan{Table::holding_registers, address, read_be16(request_pdu, 3)};
        case 22: return DataSpan{Table::holding_registers, address, 1};
        case 23:
            if (request_pdu.size() < 9) return std::nullopt;
            return DataSpan{Table::holding_registers, read_be16(request_pdu, 5), read_be16(request_pdu, 7)};
        default: return std::nullopt;
    }
}

}  // namespace loopwire::codec
