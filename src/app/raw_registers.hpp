#pragma once
// TABLE ADDRESS [COUNT] of `loopwire read` and `loopwire monitor` on a device without a profile:
// which registers to read, and how to show them: plain 16-bit words, or with --type,
// --word-order, --byte-swap and --scale as the numbers they hold (client/raw_values.hpp).
// --base 1 takes and shows addresses numbered from 1, as many device manuals list them, and
// reference addresses (40001) that name their table.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "client/link.hpp"
#include "client/raw_values.hpp"
#include "client/register_monitor.hpp"
#include "codec/pdu.hpp"
#include "common/result.hpp"

namespace loopwire::app {

struct ReadTable {
    const char* name;
    codec::FunctionCode function;
    unsigned most_per_request;  // Modbus application protocol V1.1b3, 6.1-6.4
    bool bits;
};

// holding, input, coils or discrete; nullptr for anything else.
const ReadTable* find_read_table(const std::string& name);

// The typing options as given on the command line.
struct RawTypeOptions {
    std::string type;        // empty: not given
    std::string word_order;  // empty: not given (big)
    bool byte_swap = false;
    std::string scale;       // empty: not given
    int base = 0;

    void add_to(CLI::App& command);
    // Whether any of them was given (they apply to TABLE ADDRESS [COUNT] only, not to names).
    bool any_given() const;
    // The error for giving them where they do not apply.
    static Error not_with_names();
};

// One parsed TABLE ADDRESS [COUNT]: COUNT counts values of the type (a float32 takes two
// registers), 1 by default.
struct RawRequest {
    const ReadTable* table = nullptr;
    unsigned address = 0;        // the first address as typed, in the --base numbering
    int base = 0;
    std::uint16_t wire_address = 0;
    unsigned last_wire = 0xFFFF; // the last wire address the numbering reaches (9998 for 40001..49999)
    unsigned count = 1;          // values
    unsigned registers = 1;      // count * registers per value
    bool typed = false;          // --type, --word-order, --byte-swap or --scale given
    device::RawLayout layout;
    std::optional<device::RawScale> scale;
};

// `arguments` are TABLE ADDRESS [COUNT], or REFERENCE [COUNT] where a reference address names
// its table (40001 is holding register 1; also holding 40001 with --base 1). Usage errors say
// what was wrong: an unknown table or type (listing the choices), typing options on bits, an
// address outside the --base numbering, values that would run past the last register.
Result<RawRequest> parse_raw_request(const std::vector<std::string>& arguments, const RawTypeOptions& options);

// TABLE ADDRESS VALUE... (or REFERENCE VALUE...) of `loopwire write`: the registers or coils to
// write, checked as a read's are, with each VALUE encoded by the typing options.
struct RawWrite {
    RawRequest target;                // table holding or coils; count = values, registers = words
    std::vector<std::string> values;  // as typed
    std::vector<std::uint16_t> words; // what goes on the wire, in order
    unsigned each = 1;                // registers per value
};
Result<RawWrite> parse_raw_write(const std::vector<std::string>& arguments, const RawTypeOptions& options);

// The most one write request may carry on a link of this URL, a whole number of values; a usage
// error for a value of several registers on a Linking link, which writes one per message.
Result<unsigned> per_write_on(const std::string& link, const RawWrite& write);

// Reads the request's registers (or bits) in as few requests as the protocol allows;
// `per_request` is the most one request may ask for (1 on a Linking link).
// client/register_monitor.hpp reads them; this is the range it is given.
device::RegisterRange register_range(std::uint8_t unit, const RawRequest& request, unsigned per_request);
Result<std::vector<std::uint16_t>> read_raw(device::Master& master, std::uint8_t unit, const RawRequest& request,
                                            unsigned per_request);

// The most one request may read on a link of this URL: the table's limit, or 1 on Linking.
Result<unsigned> per_request_on(const std::string& link, const RawRequest& request);

// One value as shown: its first address (in the --base numbering), the number (scaled when
// --scale was given) and the registers it came from.
struct RawReading {
    unsigned address = 0;
    device::RawNumber number;
    std::vector<std::uint16_t> registers;
};
std::vector<RawReading> raw_readings(const RawRequest& request, const std::vector<std::uint16_t>& words);

// The number for JSON: an integer, a double, or null for a NaN or an infinity (JSON has none;
// the registers still say what was read).
nlohmann::ordered_json number_json(const device::RawNumber& number);

// What the options said, for JSON outputs: "type", "word_order", "byte_swap", "scale" (and
// "base" when 1).
void describe_typing(const RawRequest& request, nlohmann::ordered_json& out);

// The help text of the positional arguments and of --type, shared by read and monitor.
extern const char* const raw_count_help;

}  // namespace loopwire::app
