#pragma once
// The gateway configuration's tables and keys as data: each key's type, default, bounds and
// meaning, written once. The parser (gateway_config.cpp) takes each table's allowed keys from
// here, so no key is accepted that is not described; `loopwire gateway --print-config` (a
// complete commented example) and the man page loopwire-gateway.toml(5) are written from it.
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace loopwire::gateway {

struct ConfigTable {
    std::string_view name;     // "mqtt", "lines.devices": the key path without indexes
    std::string_view header;   // "[mqtt]", "[[lines.devices]]"
    std::string_view meaning;  // what the table is for, and what its absence means
    bool example_commented = false;  // `--print-config` writes it commented out, with all its keys
};

struct ConfigKey {
    std::string_view table;          // ConfigTable::name
    std::string_view key;
    std::string_view type;           // "string", "duration", "integer", "number", "boolean", "list of strings", "file"
    std::string_view default_value;  // how the default reads; empty: the key is required
    std::string_view bounds;         // the values taken, as the parser enforces them; empty: any of the type
    std::string_view meaning;
    // The TOML value `--print-config` writes. Commented out there when the key's default is
    // not a value that can be written (a file that must exist, "the line's timeout").
    std::string_view example;
    bool example_commented = false;

    bool required() const { return default_value.empty(); }
};

// The numbers an integer, number or duration key takes (a duration's in milliseconds; `most`
// infinite when only its least is bounded). The parser (gateway_config.cpp) enforces these,
// read from here, and a test holds each key's `bounds` words to them.
struct ConfigRange {
    std::string_view table;
    std::string_view key;
    double least = 0;
    double most = 0;
};

// In the order a configuration file is written.
std::span<const ConfigTable> config_tables();
std::span<const ConfigKey> config_keys();
std::span<const ConfigRange> config_ranges();

// The range of an integer or number key; throws std::logic_error for a key the schema gives
// none (a parser asking for it is a programming error, which the configuration tests meet).
const ConfigRange& config_range(std::string_view table, std::string_view key);
// The key's description; throws std::logic_error for a key the schema does not describe.
const ConfigKey& config_key(std::string_view table, std::string_view key);

// What a table of that name may hold: its keys and the tables below it ("lines" holds
// "devices"); "" is the file's top level, which holds the top tables.
std::vector<std::string_view> config_keys_of(std::string_view table);

// `loopwire gateway --print-config`: every table and key with its meaning, default and bounds
// as comments; the file passes `--check` as printed.
std::string commented_example_config();

}  // namespace loopwire::gateway
