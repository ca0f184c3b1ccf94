#include "profile/request_planner.hpp"

#include <algorithm>
#include <cassert>
#include <map>
#include <set>

namespace loopwire::device {
namespace {

using codec::is_bit_table;

bool supports(const Profile& profile, std::uint8_t function) {
    return std::find(profile.function_codes.begin(), profile.function_codes.end(), function) !=
           profile.function_codes.end();
}

int wire_address(const Parameter& parameter, int address_offset) {
    const int address = parameter.address + address_offset;
    assert(address >= 0 && address <= 0xFFFF && "address_offset moves a parameter off the 16-bit address space");
    return address;
}

// Wire addresses of one table the device answers for, where it refuses unmapped ones: every
// readable entry of the profile, wanted or not (reading a neighbour nobody asked for is harmless;
// a write-only or unlisted address would get exception 2).
std::set<int> readable_addresses(const Profile& profile, Table table, int address_offset) {
    std::set<int> addresses;
    for (const Parameter& parameter : profile.parameters) {
        if (parameter.table == table && parameter.readable) addresses.insert(wire_address(parameter, address_offset));
    }
    return addresses;
}

// Greedy cover of sorted addresses: each block starts at the first address not yet read and
// takes every following wanted address within `limit` words of it. Where a block may span
// anything (`contiguous` empty), this is optimal for covering points with windows of fixed
// length (the first window can always be slid to start at the first point). Otherwise the
// caller splits the addresses into runs of consecutive readable addresses first, and blocks
// never span two runs.
std::vector<std::pair<int, int>> cover(const std::vector<int>& addresses, unsigned limit) {
    std::vector<std::pair<int, int>> blocks;  // first, last
    for (std::size_t i = 0; i < addresses.size();) {
        const int first = addresses[i];
        std::size_t j = i;
        while (j + 1 < addresses.size() && addresses[j + 1] - first < static_cast<int>(limit)) ++j;
        blocks.emplace_back(first, addresses[j]);
        i = j + 1;
    }
    return blocks;
}

// Splits sorted wanted addresses where the addresses between two neighbours are not all readable.
std::vector<std::vector<int>> runs(const std::vector<int>& addresses, const std::set<int>& readable) {
    std::vector<std::vector<int>> result;
    for (std::size_t i = 0; i < addresses.size(); ++i) {
        bool joined = false;
        if (i > 0) {
            joined = true;
            for (int address = addresses[i - 1] + 1; address < addresses[i] && joined; ++address) {
                joined = readable.contains(address);
            }
        }
        if (!joined) result.emplace_back();
        result.back().push_back(addresses[i]);
    }
    return result;
}

std::vector<ReadBlock> plan_table(const Profile& profile, Table table, const std::vector<const Parameter*>& wanted,
                                  int address_offset) {
    std::vector<int> addresses;
    for (const Parameter* parameter : wanted) addresses.push_back(wire_address(*parameter, address_offset));
    std::sort(addresses.begin(), addresses.end());
    addresses.erase(std::unique(addresses.begin(), addresses.end()), addresses.end());

    const unsigned limit = is_bit_table(table) ? profile.limits.read_bits : profile.limits.read_registers;
    std::vector<std::vector<int>> pieces{addresses};
    if (!profile.unmapped_reads_answered) pieces = runs(addresses, readable_addresses(profile, table, address_offset));

    std::vector<ReadBlock> blocks;
    for (const auto& piece : pieces) {
        for (const auto& [first, last] : cover(piece, limit)) {
            ReadBlock block;
            block.table = table;
            block.wire_address = static_cast<std::uint16_t>(first);
            block.count = static_cast<std::uint16_t>(last - first + 1);
            for (const Parameter* parameter : wanted) {
                const int address = wire_address(*parameter, address_offset);
                if (address >= first && address <= last) block.parameters.push_back(parameter);
            }
            blocks.push_back(std::move(block));
        }
    }
    return blocks;
}

}  // namespace

std::vector<ReadBlock> plan_reads(const Profile& profile, const std::vector<const Parameter*>& wanted,
                                  int address_offset) {
    // Per table, once each, readable only, in address order (then profile order).
    std::map<Table, std::vector<const Parameter*>> by_table;
    std::set<const Parameter*> seen;
    for (const Parameter* parameter : wanted) {
        if (parameter == nullptr || !parameter->readable || !seen.insert(parameter).second) continue;
        by_table[parameter->table].push_back(parameter);
    }
    std::vector<ReadBlock> blocks;
    for (auto& [table, parameters] : by_table) {
        std::stable_sort(parameters.begin(), parameters.end(),
                         [](const Parameter* a, const Parameter* b) { return a->address < b->address; });
        for (ReadBlock& block : plan_table(profile, table, parameters, address_offset)) blocks.push_back(std::move(block));
    }
    return blocks;
}

std::vector<WriteBlock> plan_writes(const Profile& profile, const std::vector<PlannedWrite>& writes,
                                    int address_offset) {
    std::vector<WriteBlock> blocks;
    for (const PlannedWrite& write : writes) {
        const Table table = write.parameter->table;
        const bool bits = is_bit_table(table);
        const bool multiple = supports(profile, bits ? 15 : 16);
        const unsigned limit = bits ? profile.limits.write_bits : profile.limits.write_registers;
        const int address = wire_address(*write.parameter, address_offset);
        if (!blocks.empty()) {
            WriteBlock& last = blocks.back();
            const bool neighbour = last.table == table && address == last.wire_address + static_cast<int>(last.values.size());
            if (multiple && neighbour && last.values.size() < limit) {
                last.values.push_back(write.raw);
                last.parameters.push_back(write.parameter);
                continue;
            }
        }
        blocks.push_back(WriteBlock{table, static_cast<std::uint16_t>(address), {write.raw}, {write.parameter}, false});
    }
    for (WriteBlock& block : blocks) {
        const bool single_supported = supports(profile, is_bit_table(block.table) ? 5 : 6);
        block.single = block.values.size() == 1 && single_supported;
    }
    return blocks;
}

}  // namespace loopwire::device
