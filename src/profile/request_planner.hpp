#pragma once
// The fewest requests that read or write a set of parameters within a device's limits.
#include <cstdint>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "profile/profile.hpp"

namespace loopwire::device {

struct ReadBlock {
    Table table = Table::holding_registers;
    std::uint16_t wire_address = 0;
    std::uint16_t count = 0;
    std::vector<const Parameter*> parameters;  // the wanted ones inside the block, by address
};

// Reads every parameter in `wanted` (plus nothing else it does not need) in the fewest
// requests: each block stays within the device's per-request limit for its table, and spans
// unmapped addresses only where the device answers them (profile.unmapped_reads_answered).
// Bits and words go in separate blocks (function 1/2 vs 3/4). `address_offset` is added to
// every listed address (AC20 J-BUS numbering: +1). Duplicates in `wanted` are read once.
// The result is optimal: greedy left-to-right cover per run of readable addresses.
// Where unmapped reads are refused, a block may still span readable entries nobody asked for
// (reading them is harmless) but never an unlisted or write-only address. Write-only entries in
// `wanted` cannot be read and are left out. Blocks come per table (holding, input, coils,
// discrete), in address order; each block's `parameters` are the wanted ones inside it.
std::vector<ReadBlock> plan_reads(const Profile& profile, const std::vector<const Parameter*>& wanted,
                                  int address_offset = 0);

struct WriteBlock {
    Table table = Table::holding_registers;
    std::uint16_t wire_address = 0;
    std::vector<std::uint16_t> values;
    std::vector<const Parameter*> parameters;
    bool single = false;  // send as function 6/5 (one value, device supports it)
};

struct PlannedWrite {
    const Parameter* parameter;
    std::uint16_t raw;
};

// Groups writes at consecutive addresses into multiple-write requests (function 16/15, within
// the write limit) where the device supports them; single writes use function 6/5 where
// supported. Writes keep their given order between blocks (order can matter: ranges bounded by
// other parameters), so only neighbours in the given order that are also neighbours in address
// are merged.
std::vector<WriteBlock> plan_writes(const Profile& profile, const std::vector<PlannedWrite>& writes,
                                    int address_offset = 0);

// Names or unique mnemonics (case-insensitive), group names, or "all" (every readable
// parameter) to parameters, in the order given, without duplicates. Errors name what was not
// found, or list the candidates of an ambiguous mnemonic.
// Each text is tried as: exact name; name ignoring case; the profile's aliases ignoring case (PV,
// SP, OUT; the primary of an ambiguous mnemonic); mnemonic ignoring case (one match, or
// an error listing "name (mnemonic, table address)" of every candidate); group ignoring case
// (its readable members, hidden ones included: naming the group asks for them); "all" (every
// readable parameter not marked hidden). "group:NAME" names a group directly, for groups a
// mnemonic shadows (TC10 group SP vs set point SP). Names resolve to parameters whatever their
// access, since the same names serve writes.
Result<std::vector<const Parameter*>> resolve_parameters(const Profile& profile, const std::vector<std::string>& names);

}  // namespace loopwire::device
