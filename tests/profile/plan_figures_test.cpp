// The cost of reading a whole device over Modbus RTU, printed for the record: every request is
// 8 bytes (unit, function, address, count, CRC); a reply is 5 + 2 x count bytes for registers
// and 5 + ceil(bits / 8) for bits (unit, function, byte count, data, CRC).
#include <iostream>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "profile/request_planner.hpp"
#include "planner_support.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using testing::builtin;
using testing::every_readable;
using codec::is_bit_table;

struct RtuCost {
    std::size_t requests = 0;
    std::size_t request_bytes = 0;
    std::size_t reply_bytes = 0;
    std::size_t words_or_bits = 0;
};

constexpr std::size_t rtu_read_request_bytes = 8;

std::size_t rtu_reply_bytes(const ReadBlock& block) {
    return 5 + (is_bit_table(block.table) ? (block.count + 7u) / 8u : 2u * block.count);
}

RtuCost cost_of(const std::vector<ReadBlock>& blocks) {
    RtuCost cost;
    for (const ReadBlock& block : blocks) {
        ++cost.requests;
        cost.request_bytes += rtu_read_request_bytes;
        cost.reply_bytes += rtu_reply_bytes(block);
        cost.words_or_bits += block.count;
    }
    return cost;
}

int function_code(Table table) {
    switch (table) {
        case Table::coils: return 1;
        case Table::discrete_inputs: return 2;
        case Table::holding_registers: return 3;
        case Table::input_registers: return 4;
    }
    return 3;
}

void print_plan(const Profile& profile, const std::string& what, const std::vector<const Parameter*>& wanted) {
    const auto blocks = plan_reads(profile, wanted);
    const RtuCost cost = cost_of(blocks);
    std::cout << fmt::format("{} {}: {} parameters, {} requests, {} request + {} reply = {} bytes on RTU\n", profile.id,
                             what, wanted.size(), cost.requests, cost.request_bytes, cost.reply_bytes,
                             cost.request_bytes + cost.reply_bytes);
    for (const ReadBlock& block : blocks) {
        std::cout << fmt::format("  FC{:02} {:<8} {:5}..{:<5} count {:2}  {} parameters, reply {} bytes\n",
                                 function_code(block.table), table_name(block.table), block.wire_address,
                                 block.wire_address + block.count - 1, block.count, block.parameters.size(),
                                 rtu_reply_bytes(block));
    }
    EXPECT_EQ(static_cast<int>(cost.requests), testing::minimum_blocks(profile, wanted));
}

TEST(PlanFigures, FullDeviceReadOnRtu) {
    for (const std::string& id : testing::profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        print_plan(*profile, "every readable entry", every_readable(*profile));
        const auto all = resolve_parameters(*profile, {"all"});
        ASSERT_TRUE(all.ok());
        print_plan(*profile, "'all' (hidden left out)", *all);
    }
}

TEST(PlanFigures, ReplyBytesFollowTheFrameLayout) {
    EXPECT_EQ(rtu_reply_bytes(ReadBlock{Table::holding_registers, 0, 20, {}}), 45u);
    EXPECT_EQ(rtu_reply_bytes(ReadBlock{Table::coils, 0, 24, {}}), 8u);
    EXPECT_EQ(rtu_reply_bytes(ReadBlock{Table::coils, 0, 9, {}}), 7u);
}

}  // namespace
}  // namespace loopwire::device
