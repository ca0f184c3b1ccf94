#pragma once
// An independent measure of what the planner should achieve: the fewest blocks that cover a set
// of addresses, by dynamic programming over every split (no greedy argument needed).
#include <algorithm>
#include <climits>
#include <set>
#include <vector>

#include "profile/profile.hpp"
#include "profile/request_planner.hpp"

namespace loopwire::device::testing {

inline unsigned read_limit(const Profile& profile, Table table) {
    return codec::is_bit_table(table) ? profile.limits.read_bits : profile.limits.read_registers;
}

inline std::set<int> readable_addresses(const Profile& profile, Table table, int offset = 0) {
    std::set<int> addresses;
    for (const Parameter& parameter : profile.parameters) {
        if (parameter.table == table && parameter.readable) addresses.insert(parameter.address + offset);
    }
    return addresses;
}

inline std::vector<const Parameter*> every_readable(const Profile& profile) {
    std::vector<const Parameter*> all;
    for (const Parameter& parameter : profile.parameters) {
        if (parameter.readable) all.push_back(&parameter);
    }
    return all;
}

// best[j] = fewest blocks covering the first j addresses; a block may cover addresses[i..j-1]
// when they span at most `limit` and, on a device that refuses unmapped reads, every address
// between them is a readable entry.
inline int minimum_blocks(const Profile& profile, Table table, const std::vector<const Parameter*>& wanted,
                          int offset = 0) {
    std::set<int> unique;
    for (const Parameter* parameter : wanted) {
        if (parameter->table == table && parameter->readable) unique.insert(parameter->address + offset);
    }
    const std::vector<int> addresses(unique.begin(), unique.end());
    const std::set<int> readable = readable_addresses(profile, table, offset);
    const auto spannable = [&](int first, int last) {
        if (profile.unmapped_reads_answered) return true;
        for (int address = first; address <= last; ++address) {
            if (!readable.contains(address)) return false;
        }
        return true;
    };
    const unsigned limit = read_limit(profile, table);
    std::vector<int> best(addresses.size() + 1, INT_MAX);
    best[0] = 0;
    for (std::size_t j = 1; j <= addresses.size(); ++j) {
        for (std::size_t i = 0; i < j; ++i) {
            const bool fits = addresses[j - 1] - addresses[i] < static_cast<int>(limit);
            if (best[i] != INT_MAX && fits && spannable(addresses[i], addresses[j - 1])) {
                best[j] = std::min(best[j], best[i] + 1);
            }
        }
    }
    return best.back();
}

inline int minimum_blocks(const Profile& profile, const std::vector<const Parameter*>& wanted, int offset = 0) {
    int total = 0;
    for (const Table table : {Table::holding_registers, Table::input_registers, Table::coils, Table::discrete_inputs}) {
        total += minimum_blocks(profile, table, wanted, offset);
    }
    return total;
}

}  // namespace loopwire::device::testing
