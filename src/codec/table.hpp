#pragma once
// The four tables of the Modbus data model (Modbus application protocol V1.1b3, 4.3): one enum
// for every layer. Profiles name them, the planner and the client read them, the simulators and
// the register bank serve them, and the CLI takes their names.
#include <cstdint>
#include <optional>
#include <string_view>

#include "codec/pdu.hpp"

namespace loopwire::codec {

enum class Table { coils, discrete_inputs, holding_registers, input_registers };

constexpr bool is_bit_table(Table table) { return table == Table::coils || table == Table::discrete_inputs; }

// The words profiles and the command line use: "coils", "discrete", "holding", "input".
std::string_view table_name(Table table);
std::optional<Table> table_named(std::string_view name);

// The function that reads the table (1-4), and the table a read function reads.
FunctionCode read_function(Table table);
std::optional<Table> table_read_by(std::uint8_t function);

}  // namespace loopwire::codec
