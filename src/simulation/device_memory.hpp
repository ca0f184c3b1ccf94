#pragma once
// The words and bits of one simulated device: one cell per profile parameter, keyed by the
// profile's own numbering, with the profile's address mirrors folded in (TC10 §5: 10240… are
// the same parameters as 640…). Each cell keeps what the device answers now (RAM) and what
// survives a restart (EEPROM / non-volatile memory); RAM-only parameters (profile ram_only)
// have no saved value.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "profile/profile.hpp"
#include "profile/values.hpp"

namespace loopwire::device {

struct MemoryCell {
    const Parameter* parameter = nullptr;
    std::uint16_t raw = 0;    // what a read answers (before the model's on_read)
    std::uint16_t saved = 0;  // what a restart brings back; equal to raw unless written to RAM only
};

// Where a write lands: RAM and non-volatile memory (Modbus writes; Linking W), or RAM only
// (Linking M; process values the model computes).
enum class Persistence { saved, ram_only };

class DeviceMemory {
public:
    // Every parameter starts at a sensible default (see default_raw in the .cpp) and the
    // profile's identification words hold the values `loopwire scan` matches.
    explicit DeviceMemory(std::shared_ptr<const Profile> profile);

    // The cell a wire address names, or nullptr where the profile lists nothing.
    MemoryCell* find(Table table, std::uint16_t wire_address);
    // The cell of a parameter by profile name, or nullptr for a name the profile lacks.
    MemoryCell* cell(std::string_view name);
    const MemoryCell* cell(std::string_view name) const;

    // Stores `raw`; a ram_only parameter is never saved whatever `persistence` says.
    void store(MemoryCell& cell, std::uint16_t raw, Persistence persistence);

    // The raw words `parameter`'s decimals and range depend on, from memory with `pending`
    // (values earlier in the same write request) laid over it.
    RawValues known_for(const Parameter& parameter, const RawValues& pending) const;

    // Whether the profile lists any parameter in `table` (AC20: no discrete or input tables).
    bool has_table(Table table) const;

    // Non-volatile contents by parameter name (for --state), and their reload after a restart.
    // Unknown names in `saved` are returned so the caller can report them.
    RawValues saved_values() const;
    std::vector<std::string> load_saved(const RawValues& saved);
    // Goes up whenever a saved value changes, so a host knows when to write the state file.
    std::uint64_t saved_generation() const { return saved_generation_; }

    // Every cell back to its power-on default (TC10 word 19 = 481, AC20 load defaults).
    void reset_to_defaults();

private:
    using Key = std::pair<Table, std::uint16_t>;
    std::uint16_t own_address(Table table, std::uint16_t wire_address) const;
    void set_identification();

    std::shared_ptr<const Profile> profile_;
    std::map<Key, MemoryCell> cells_;
    std::uint64_t saved_generation_ = 0;
};

}  // namespace loopwire::device
