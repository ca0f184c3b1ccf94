#pragma once
// Device profiles: everything loopwire knows about one device model, loaded from
// profiles/*.json and validated against profiles/profile.schema.json (docs/DESIGN.md, "Device
// knowledge is data").
#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "codec/table.hpp"
#include "common/result.hpp"

namespace loopwire::device {

using codec::Table;
using codec::table_name;

enum class ValueType { int16, uint16, enumeration, bitfield, boolean };

// A fixed number in engineering units, or the current value of another parameter.
using Bound = std::variant<double, std::string>;

struct SpecialValue {
    std::int32_t raw = 0;      // as written in the profile (-32768..65535)
    std::string state;         // "not-available", "under-range", ...
    std::string meaning;
};

// What it takes to read a parameter that bounds another one's range: copied from that entry
// when the profile is loaded, so a range can be checked from the bounded Parameter alone
// (values.hpp), with the bound decoded in its own type and decimals.
struct BoundSource {
    ValueType type = ValueType::int16;
    std::variant<int, std::string> decimals = 0;
    std::vector<SpecialValue> special;
    std::string unit;
};

// One word a unit follows (TC10 unit, AC20 PV.SL and tP.In, ramp/soak UNIT): that word's raw
// value -> the unit ("°C", "%C", "mV"). A Parameter's rules are tried in order; the first whose
// word holds a listed value gives the unit (AC20 dew point: PV.SL lists no unit, tP.In does).
struct UnitRule {
    std::string parameter;
    std::map<std::int32_t, std::string> units;
};

struct Parameter {
    std::string name;
    std::string mnemonic;
    std::string group;
    std::string description;
    Table table = Table::holding_registers;
    std::uint16_t address = 0;            // in the device's own numbering
    ValueType type = ValueType::uint16;
    std::variant<int, std::string> decimals = 0;  // fixed, or the parameter giving them
    std::string unit;                     // fixed; empty when unit_from decides or there is none
    std::vector<UnitRule> unit_from;      // the unit follows the configuration (values.hpp unit_of)
    std::string unitless;                 // why a number has no physical unit: count, code, ratio, raw
    bool readable = true;
    bool writable = false;
    std::vector<std::string> write_modes;
    // Whether `mode` ("remote", "control", "configuration", ...) is one the word is written in.
    bool writable_in(std::string_view mode) const {
        return std::find(write_modes.begin(), write_modes.end(), mode) != write_modes.end();
    }
    std::optional<Bound> min;
    std::optional<Bound> max;
    // "range": {"counts": true}: the fixed min/max are display counts, divided by 10^decimals at
    // the current decimals (TC10 §5.3 "-1999 ... 9999" for dP values; ramp/soak §7 "follow DP").
    bool range_in_counts = false;
    std::map<std::string, BoundSource> bound_sources;  // by name, for every parameter min/max name
    std::map<std::int32_t, std::string> enum_labels;
    std::map<unsigned, std::string> bit_names;
    std::vector<SpecialValue> special;    // the parameter's own, then the profile's word_specials
    bool ram_only = false;
    bool persistent = false;  // "storage": "persistent": kept across power-off (configuration)
    bool hidden = false;
    std::string source;
    std::string note;
};

struct Limits {
    unsigned read_bits = 2000;
    unsigned read_registers = 125;
    unsigned write_bits = 1968;
    unsigned write_registers = 123;
};

struct AddressMirror {
    Table table = Table::holding_registers;
    std::uint16_t first = 0;
    std::uint16_t last = 0;
    int offset = 0;
};

struct NumberingAlternative {
    std::string name;       // "jbus"
    int offset = 0;         // wire address = listed address + offset
    std::string selected_by_parameter;
    std::int32_t selected_by_value = 0;
};

struct IdentificationCheck {
    std::string parameter;
    std::int32_t equals = 0;
};

struct Profile {
    std::string id;
    std::string title;
    // Who makes the device and its model name (Home Assistant's device block); empty when the
    // manual does not say.
    std::string manufacturer;
    std::string model;
    std::string manual_file;
    std::string manual_document;
    std::vector<std::string> protocols;
    std::uint32_t default_baud = 19200;
    unsigned default_data_bits = 8;
    std::string default_parity = "even";
    unsigned default_stop_bits = 1;
    std::vector<std::uint8_t> function_codes;
    Limits limits;
    std::vector<std::string> parities;     // serial_defaults.parities: what the device can be set to
    unsigned first_unit = 1;               // unit_ids: the addresses the device can be set to
    unsigned last_unit = 247;              // (AC20, ramp/soak 1-255; TC10 1-254)
    bool broadcast = false;                // unit 0 writes are executed
    bool unmapped_reads_answered = false;  // the AC20 answers 8000h for unmapped words
    std::uint16_t unmapped_value = 0x8000; // what an unmapped word reads as, when answered
    // How the device answers what it cannot serve (NOTES.md, "Slave behaviour on errors").
    bool silent_on_unsupported_function = false;  // AC20: no reply instead of exception 1
    std::uint8_t limit_exception = 3;             // over the per-request limits (AC20: 9)
    bool read_only_writes_ignored = false;        // AC20: skipped; others: exception 2
    bool block_writes_in_order = false;           // AC20: abort at the first error; others: all or nothing
    std::map<std::uint8_t, std::string> exception_names;
    std::vector<NumberingAlternative> numberings;
    std::vector<AddressMirror> mirrors;
    std::vector<IdentificationCheck> identification;
    // Per mode, what a master can read to tell that it holds (AC20: bit 218 = remote).
    std::map<std::string, std::vector<IdentificationCheck>> mode_requirements;
    std::vector<std::string> identification_report;
    // Words people type for a parameter (PV, SP, OUT; a primary for an ambiguous mnemonic):
    // alias -> parameter name, every name checked to exist.
    std::map<std::string, std::string> aliases;
    std::vector<Parameter> parameters;

    const Parameter* find(std::string_view name) const;  // exact name
};

// Loads and validates one profile. Errors (ErrorKind::usage) name the file, the JSON pointer
// and what is wrong: "profiles/tc10.json: /parameters/12/access: must be one of r, w, rw".
// Beyond the schema: unique names, unique (table, address) pairs, references to existing
// parameters (the full list, and the rule that two entries may share an address only when both
// carry a "note" explaining the manual glitch, is in profile_checks.hpp). A key given twice in
// one JSON object is an error too. A value of a type the schema failed to catch is an error
// containing profile_type_gap_message, never an uncaught exception.
inline constexpr const char* profile_type_gap_message = "a value has a type loopwire cannot use";
Result<Profile> load_profile_text(const std::string& json_text, const std::string& origin);
Result<Profile> load_profile_file(const std::string& path);

// The profiles compiled into loopwire (ac20, rampsoak, tc10), validated on first use.
const std::vector<std::string>& builtin_profile_ids();
Result<std::shared_ptr<const Profile>> builtin_profile(const std::string& id);

}  // namespace loopwire::device
