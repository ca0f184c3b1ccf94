// The read planner on the real profiles: as few requests as an exhaustive search finds, within
// each device's limits, across unmapped addresses only where the device answers them.
#include <random>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "profile/request_planner.hpp"
#include "planner_support.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using testing::builtin;
using testing::every_readable;
using testing::minimum_blocks;
using testing::parameter;
using testing::profile_ids;
using testing::read_limit;
using testing::readable_addresses;

// Every wanted readable parameter is in exactly one block that covers its address; blocks stay
// within the limit and hold one table each.
void expect_covers(const Profile& profile, const std::vector<ReadBlock>& blocks,
                   const std::vector<const Parameter*>& wanted, int offset = 0) {
    std::map<const Parameter*, int> seen;
    for (const ReadBlock& block : blocks) {
        EXPECT_GE(block.count, 1);
        EXPECT_LE(block.count, read_limit(profile, block.table)) << profile.id;
        for (const Parameter* parameter : block.parameters) {
            ++seen[parameter];
            EXPECT_EQ(parameter->table, block.table);
            const int address = parameter->address + offset;
            EXPECT_GE(address, block.wire_address) << parameter->name;
            EXPECT_LT(address, block.wire_address + block.count) << parameter->name;
        }
    }
    for (const Parameter* parameter : wanted) {
        if (parameter->readable) {
            EXPECT_EQ(seen[parameter], 1) << profile.id << " " << parameter->name;
        } else {
            EXPECT_EQ(seen.count(parameter), 0u) << parameter->name << " is write-only";
        }
    }
}

// Where the device refuses unmapped addresses, every address a block spans is a readable entry.
void expect_no_unmapped_span(const Profile& profile, const std::vector<ReadBlock>& blocks) {
    for (const ReadBlock& block : blocks) {
        const auto readable = readable_addresses(profile, block.table);
        for (int address = block.wire_address; address < block.wire_address + block.count; ++address) {
            EXPECT_TRUE(readable.contains(address))
                << profile.id << ": block at " << block.wire_address << " spans unmapped " << address;
        }
    }
}

TEST(ReadPlanner, FullDeviceReadIsOptimal) {
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        const auto wanted = every_readable(*profile);
        const auto blocks = plan_reads(*profile, wanted);
        expect_covers(*profile, blocks, wanted);
        EXPECT_EQ(static_cast<int>(blocks.size()), minimum_blocks(*profile, wanted)) << id;
    }
}

TEST(ReadPlanner, RandomSelectionsAreOptimal) {
    std::mt19937 random(20240601);  // fixed seed: the same selections on every run
    for (const std::string& id : profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        const auto all = every_readable(*profile);
        for (int round = 0; round < 300; ++round) {
            std::vector<const Parameter*> wanted;
            const auto percent = 5 + random() % 60;
            for (const Parameter* parameter : all) {
                if (random() % 100 < percent) wanted.push_back(parameter);
            }
            const auto blocks = plan_reads(*profile, wanted);
            expect_covers(*profile, blocks, wanted);
            ASSERT_EQ(static_cast<int>(blocks.size()), minimum_blocks(*profile, wanted)) << id << " round " << round;
            if (!profile->unmapped_reads_answered) expect_no_unmapped_span(*profile, blocks);
        }
    }
}

TEST(ReadPlanner, Tc10AndRampsoakPlansNeverCrossUnmappedAddresses) {
    for (const std::string id : {"tc10", "rampsoak"}) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        ASSERT_FALSE(profile->unmapped_reads_answered);
        expect_no_unmapped_span(*profile, plan_reads(*profile, every_readable(*profile)));
    }
}

// Two readable neighbours with an unmapped address between them, close enough for one request:
// the TC10 needs two, the AC20 (which answers 8000h for unmapped words) one.
std::pair<const Parameter*, const Parameter*> pair_around_hole(const Profile& profile, Table table) {
    const auto readable = readable_addresses(profile, table);
    for (const Parameter& low : profile.parameters) {
        if (low.table != table || !low.readable) continue;
        if (readable.contains(low.address + 1) || !readable.contains(low.address + 2)) continue;
        for (const Parameter& high : profile.parameters) {
            if (high.table == table && high.readable && high.address == low.address + 2) return {&low, &high};
        }
    }
    return {nullptr, nullptr};
}

TEST(ReadPlanner, HolesSplitTc10ButNotAc20) {
    const auto tc10 = builtin("tc10");
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(tc10 && ac20);
    const auto [tc10_low, tc10_high] = pair_around_hole(*tc10, Table::holding_registers);
    ASSERT_NE(tc10_low, nullptr);
    EXPECT_EQ(plan_reads(*tc10, {tc10_low, tc10_high}).size(), 2u);
    const auto [ac20_low, ac20_high] = pair_around_hole(*ac20, Table::holding_registers);
    ASSERT_NE(ac20_low, nullptr);
    const auto blocks = plan_reads(*ac20, {ac20_low, ac20_high});
    ASSERT_EQ(blocks.size(), 1u);
    EXPECT_EQ(blocks[0].count, 3);
}

TEST(ReadPlanner, Ac20FullReadSpansUnmappedAddresses) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    bool spans_hole = false;
    for (const ReadBlock& block : plan_reads(*ac20, every_readable(*ac20))) {
        const auto readable = readable_addresses(*ac20, block.table);
        for (int address = block.wire_address; address < block.wire_address + block.count; ++address) {
            spans_hole = spans_hole || !readable.contains(address);
        }
    }
    EXPECT_TRUE(spans_hole) << "the AC20 answers unmapped words with 8000h; reading across holes saves requests";
}

TEST(ReadPlanner, BitsAndWordsGoInSeparateBlocksWithinTheirLimits) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const auto blocks = plan_reads(*ac20, every_readable(*ac20));
    std::size_t bit_blocks = 0;
    for (const ReadBlock& block : blocks) {
        if (block.table == Table::coils) {
            ++bit_blocks;
            EXPECT_LE(block.count, 24);
        } else {
            EXPECT_EQ(block.table, Table::holding_registers);
            EXPECT_LE(block.count, 20);
        }
    }
    EXPECT_GT(bit_blocks, 0u);
    EXPECT_LT(bit_blocks, blocks.size());
}

TEST(ReadPlanner, JbusNumberingShiftsWireAddressesByOne) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const Parameter& sp = parameter(*ac20, "main_set_point");
    const auto modbus = plan_reads(*ac20, {&sp});
    const auto jbus = plan_reads(*ac20, {&sp}, ac20->numberings.at(0).offset);
    ASSERT_EQ(modbus.size(), 1u);
    ASSERT_EQ(jbus.size(), 1u);
    EXPECT_EQ(modbus[0].wire_address, 138);
    EXPECT_EQ(jbus[0].wire_address, 139);  // the manual's JBus column
    const auto all = every_readable(*ac20);
    const auto shifted = plan_reads(*ac20, all, 1);
    const auto plain = plan_reads(*ac20, all);
    ASSERT_EQ(shifted.size(), plain.size());
    for (std::size_t i = 0; i < plain.size(); ++i) {
        EXPECT_EQ(shifted[i].wire_address, plain[i].wire_address + 1);
        EXPECT_EQ(shifted[i].count, plain[i].count);
        EXPECT_EQ(shifted[i].parameters, plain[i].parameters);
    }
    expect_covers(*ac20, shifted, all, 1);
}

TEST(ReadPlanner, DuplicatesAreReadOnceAndWriteOnlyEntriesNotAtAll) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const Parameter& sp = parameter(*ac20, "main_set_point");
    const Parameter& start = parameter(*ac20, "start_probe_test");  // write-only bit
    ASSERT_FALSE(start.readable);
    const auto blocks = plan_reads(*ac20, {&sp, &start, &sp});
    ASSERT_EQ(blocks.size(), 1u);
    EXPECT_EQ(blocks[0].parameters, (std::vector<const Parameter*>{&sp}));
    EXPECT_TRUE(plan_reads(*ac20, {}).empty());
}

TEST(ReadPlanner, Tc10MirrorsDoNotMoveThePrimaryAddresses) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& sp = parameter(*tc10, "set_point");
    const auto blocks = plan_reads(*tc10, {&sp, &parameter(*tc10, "decimal_point")});
    ASSERT_EQ(blocks.size(), 2u);  // 641 and 717 are 76 words apart
    EXPECT_EQ(blocks[0].wire_address, 641);
    EXPECT_EQ(blocks[1].wire_address, 717);
}

TEST(ReadPlanner, BlockFillsUpToTheLimitFromTheFirstAddress) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    // The §5.1 variables 1..40, with the holes the TC10 refuses (exception 2) between some.
    std::vector<const Parameter*> wanted;
    for (const Parameter& parameter : tc10->parameters) {
        if (parameter.readable && parameter.address >= 1 && parameter.address <= 40) wanted.push_back(&parameter);
    }
    const auto blocks = plan_reads(*tc10, wanted);
    ASSERT_FALSE(blocks.empty());
    EXPECT_EQ(blocks[0].wire_address, 1);
    EXPECT_EQ(static_cast<int>(blocks.size()), minimum_blocks(*tc10, wanted));
}

}  // namespace
}  // namespace loopwire::device
