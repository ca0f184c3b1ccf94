#pragma once
// The four tables of the Modbus data model (Modbus application protocol V1.1b3, 4.3): one enum
// for every layer. Profiles name them, the planner and the client read them, the simulators and
// the register bank serve them, and the CLI takes their names.
#include <cstdint>
#include <optional>
#include <string_view>

#include "codec/pdu.hpp"
#include "common/bytes.hpp"

namespace loopwire::codec {

enum class Table { coils, discrete_inputs, holding_registers, input_registers };

constexpr bool is_bit_table(Table table) { return table == Table::coils || table == Table::discrete_inputs; }

// The words profiles and the command line use: "coils", "discrete", "holding", "input".
std::string_view table_name(Table table);
std::optional<Table> table_named(std::string_view name);

// The function that reads the table (1-4), and the table a read function reads.
FunctionCode read_function(Table table);
std::optional<Table> table_read_by(std::uint8_t function);

// The data items a request reads or writes: a run of one table's addresses.
struct DataSpan {
    Table table;
    std::uint16_t first;
    std::uint32_t count;  // up to 65536: first + count may reach past 65535 in a malformed request
    bool overlaps(const DataSpan& other) const {
        return table == other.table && first < other.first + other.count && other.first < first + count;
    }
};
// What a request of functions 1-4 reads; none for any other function or a PDU too short to say.
std::optional<DataSpan> read_span(ByteView request_pdu);
// What a request of functions 5, 6, 15, 16, 22 (mask write) or 23 (its write part) writes;
// none for any other function (which may change anything: a caller must assume it does) or a
// PDU too short to say.
std::optional<DataSpan> written_span(ByteView request_pdu);

}  // namespace loopwire::codec
