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

}  // namespace loopwire::codec
