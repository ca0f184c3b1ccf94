// The write planner: consecutive addresses merged into one multiple write (function 16/15)
// within the write limit, the given order kept, single writes as function 6/5.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "profile/request_planner.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using testing::builtin;
using testing::parameter;

std::vector<std::uint16_t> addresses_of(const std::vector<WriteBlock>& blocks) {
    std::vector<std::uint16_t> addresses;
    for (const WriteBlock& block : blocks) addresses.push_back(block.wire_address);
    return addresses;
}

TEST(WritePlanner, ConsecutiveAddressesInOrderBecomeOneMultipleWrite) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& low = parameter(*tc10, "set_point_low_limit");    // 715
    const Parameter& high = parameter(*tc10, "set_point_high_limit");  // 716
    const Parameter& sp = parameter(*tc10, "set_point");               // 717
    const auto blocks = plan_writes(*tc10, {{&low, 1}, {&high, 2}, {&sp, 3}});
    ASSERT_EQ(blocks.size(), 1u);
    EXPECT_EQ(blocks[0].wire_address, 715);
    EXPECT_EQ(blocks[0].values, (std::vector<std::uint16_t>{1, 2, 3}));
    EXPECT_EQ(blocks[0].parameters, (std::vector<const Parameter*>{&low, &high, &sp}));
    EXPECT_FALSE(blocks[0].single);
}

TEST(WritePlanner, OrderIsKeptEvenWhenSortingWouldMerge) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& low = parameter(*tc10, "set_point_low_limit");
    const Parameter& high = parameter(*tc10, "set_point_high_limit");
    const Parameter& sp = parameter(*tc10, "set_point");
    // Raise the high limit first, then the set point, then the low limit: three requests, as given.
    const auto blocks = plan_writes(*tc10, {{&high, 2}, {&sp, 3}, {&low, 1}});
    EXPECT_EQ(addresses_of(blocks), (std::vector<std::uint16_t>{716, 715}));
    ASSERT_EQ(blocks.size(), 2u);
    EXPECT_EQ(blocks[0].values, (std::vector<std::uint16_t>{2, 3}));
    EXPECT_TRUE(blocks[1].single);
    const auto reversed = plan_writes(*tc10, {{&sp, 3}, {&high, 2}, {&low, 1}});
    EXPECT_EQ(addresses_of(reversed), (std::vector<std::uint16_t>{717, 716, 715}));
}

TEST(WritePlanner, GapsAndTablesSplit) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const Parameter& sp = parameter(*ac20, "main_set_point");         // holding 138
    const Parameter& sp3 = parameter(*ac20, "auxiliary_set_point_3");  // holding 140
    const Parameter& remote = parameter(*ac20, "local_remote");        // coil 218
    const auto blocks = plan_writes(*ac20, {{&remote, 1}, {&sp, 10}, {&sp3, 30}});
    ASSERT_EQ(blocks.size(), 3u);
    EXPECT_EQ(blocks[0].table, Table::coils);
    EXPECT_TRUE(blocks[0].single);  // function 5
    EXPECT_EQ(blocks[1].wire_address, 138);
    EXPECT_EQ(blocks[2].wire_address, 140);
}

TEST(WritePlanner, WriteLimitSplitsLongRuns) {
    const auto rampsoak = builtin("rampsoak");
    ASSERT_TRUE(rampsoak);
    std::vector<PlannedWrite> writes;
    for (const Parameter& parameter : rampsoak->parameters) {
        if (parameter.writable && parameter.address >= 0x10 && writes.size() < 10) {
            if (!writes.empty() && parameter.address != writes.back().parameter->address + 1) break;
            writes.push_back({&parameter, 0});
        }
    }
    ASSERT_EQ(writes.size(), 10u) << "expected ten writable neighbours from 0x10";
    const auto blocks = plan_writes(*rampsoak, writes);
    ASSERT_EQ(blocks.size(), 2u);
    EXPECT_EQ(blocks[0].values.size(), 8u);  // §4.3: at most 8 registers per request
    EXPECT_EQ(blocks[1].values.size(), 2u);
    EXPECT_EQ(blocks[1].wire_address, blocks[0].wire_address + 8);
}

TEST(WritePlanner, JbusOffsetAppliesToWrites) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const auto blocks = plan_writes(*ac20, {{&parameter(*ac20, "main_set_point"), 1370}}, 1);
    ASSERT_EQ(blocks.size(), 1u);
    EXPECT_EQ(blocks[0].wire_address, 139);
    EXPECT_TRUE(blocks[0].single);
}

TEST(WritePlanner, FollowsTheFunctionCodesTheDeviceHas) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const Parameter& low = parameter(*tc10, "set_point_low_limit");
    const Parameter& high = parameter(*tc10, "set_point_high_limit");
    Profile without_multiple = *tc10;
    without_multiple.function_codes = {3, 6};
    const auto singles = plan_writes(without_multiple, {{&low, 1}, {&high, 2}});
    ASSERT_EQ(singles.size(), 2u);
    EXPECT_TRUE(singles[0].single && singles[1].single);
    Profile without_single = *tc10;
    without_single.function_codes = {3, 16};
    const auto multiple = plan_writes(without_single, {{&low, 1}});
    ASSERT_EQ(multiple.size(), 1u);
    EXPECT_FALSE(multiple[0].single);  // one value sent with function 16
}

}  // namespace
}  // namespace loopwire::device
