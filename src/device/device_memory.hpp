#pragma once
// The words and bits of one simulated device: one cell per profile parameter, keyed by the
// profile's own numbering, with the profile's address mirrors folded in (TC10 §5: 10240… are
// the same parameters as 640…).
#include <cstdint>
#include <map>
#include <memory>
#include <utility>

#include "device/profile.hpp"
#include "device/values.hpp"

namespace loopwire::device {

struct MemoryCell {
    const Parameter* parameter = nullptr;
    std::uint16_t raw = 0;
};

class DeviceMemory {
public:
    // Every parameter starts at a sensible default (see default_raw in the .cpp) and the
    // profile's identification words hold the values `loopwire scan` matches.
    explicit DeviceMemory(std::shared_ptr<const Profile> profile);

    // The cell a wire address names, or nullptr where the profile lists nothing.
    MemoryCell* find(Table table, std::uint16_t wire_address);

    // The raw words `parameter`'s decimals and range depend on, from memory with `pending`
    // (values earlier in the same write request) laid over it.
    RawValues known_for(const Parameter& parameter, const RawValues& pending) const;

    // Whether the profile lists any parameter in `table` (AC20: no discrete or input tables).
    bool has_table(Table table) const;

private:
    using Key = std::pair<Table, std::uint16_t>;
    std::uint16_t own_address(Table table, std::uint16_t wire_address) const;
    void set_identification();

    std::shared_ptr<const Profile> profile_;
    std::map<Key, MemoryCell> cells_;
};

}  // namespace loopwire::device
