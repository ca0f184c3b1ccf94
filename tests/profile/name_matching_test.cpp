// Names as people type them (profile/name_matching.hpp): the AC20 manual's 'ñ' typed as 'm',
// the nearest names offered on a miss, and the groups of a profile.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "profile/name_matching.hpp"
#include "profile/request_planner.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using testing::builtin;

std::string resolved_name(const Profile& profile, const std::string& text) {
    auto found = resolve_parameters(profile, {text});
    if (!found) return "error: " + found.error().message;
    return found->size() == 1 ? found->front()->name : "several";
}

TEST(NameMatching, FoldingLowersAsciiAndTypesTheManualsEnyeAsM) {
    EXPECT_EQ(folded_name("\xC3\xB1.OLL"), "m.oll");      // ñ.OLL
    EXPECT_EQ(folded_name("Alr\xC3\xB1"), "alrm");        // Alrñ
    EXPECT_EQ(folded_name("\xC3\x91" "AN"), "man");       // Ñ
    EXPECT_EQ(folded_name("SP.HL"), "sp.hl");
    EXPECT_EQ(folded_name("\xC2\xB0" "C"), "\xC2\xB0" "c");  // other non-ASCII bytes are kept
    EXPECT_TRUE(same_name("m.OLL", "\xC3\xB1.OLL"));
    EXPECT_TRUE(same_name("M.oll", "\xC3\xB1.OLL"));
    EXPECT_FALSE(same_name("n.OLL", "\xC3\xB1.OLL"));
}

TEST(NameMatching, Ac20MnemonicsAndGroupsWithEnyeAnswerToAscii) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    EXPECT_EQ(resolved_name(*ac20, "m.OLL"), "main_output_low_limit");
    EXPECT_EQ(resolved_name(*ac20, "\xC3\xB1.OLL"), "main_output_low_limit");  // as printed still works
    EXPECT_EQ(resolved_name(*ac20, "E.Am"), "external_auto_manual_control");
    EXPECT_EQ(resolved_name(*ac20, "smrt"), "smart_enable");
    EXPECT_EQ(resolved_name(*ac20, "m.rst"), "alarm_reset");
    auto timers = resolve_parameters(*ac20, {"timE"});
    ASSERT_TRUE(timers) << timers.error().message;
    EXPECT_GE(timers->size(), 6u);
    for (const auto* p : *timers) EXPECT_EQ(p->group, "ti\xC3\xB1" "E") << p->name;
    EXPECT_TRUE(resolve_parameters(*ac20, {"group:Alrm"}));
}

TEST(NameMatching, EditDistanceCountsSwapsOfNeighboursAsOne) {
    EXPECT_EQ(edit_distance("sett_point", "set_point"), 1u);
    EXPECT_EQ(edit_distance("SP.LH", "sp.hl"), 1u);
    EXPECT_EQ(edit_distance("", "abc"), 3u);
    EXPECT_EQ(edit_distance("kitten", "sitting"), 3u);
    EXPECT_EQ(edit_distance("m.OL", "\xC3\xB1.OLL"), 1u);  // measured on folded text
}

TEST(NameMatching, AMissOffersTheNearestNames) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    auto missed = resolve_parameters(*tc10, {"sett_point"});
    ASSERT_FALSE(missed);
    EXPECT_EQ(missed.error().kind, ErrorKind::usage);
    EXPECT_EQ(missed.error().message, "no parameter \"sett_point\" on tc10; did you mean set_point (SP)?");
    EXPECT_THAT(nearest_names(*tc10, "SP.LH"), ElementsAre("set_point_low_limit (SP.LL)", "set_point_high_limit (SP.HL)"));
    // Never more than three, nearest first.
    EXPECT_LE(nearest_names(*tc10, "x").size(), 3u);
    EXPECT_LE(nearest_names(*tc10, "SP.LH", 1).size(), 1u);
}

TEST(NameMatching, AMissOnAsciiForEnyeOffersTheManualsSpelling) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    EXPECT_THAT(resolve_parameters(*ac20, {"m.OLX"}).error().message,
                HasSubstr("did you mean main_output_low_limit (\xC3\xB1.OLL)"));
}

TEST(NameMatching, NothingCloseSaysWhereToLook) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    auto missed = resolve_parameters(*tc10, {"zzzzzzzzzz"});
    ASSERT_FALSE(missed);
    EXPECT_EQ(missed.error().message,
              "no parameter \"zzzzzzzzzz\" on tc10; `loopwire describe tc10` lists its names, mnemonics and groups");
}

TEST(NameMatching, GroupsInProfileOrderEachOnce) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const auto groups = group_names(*tc10);
    EXPECT_FALSE(groups.empty());
    for (const auto& group : groups) EXPECT_EQ(std::count(groups.begin(), groups.end(), group), 1) << group;
    EXPECT_NE(std::find(groups.begin(), groups.end(), "SP"), groups.end());
    auto missed = resolve_parameters(*tc10, {"group:nope"});
    ASSERT_FALSE(missed);
    EXPECT_THAT(missed.error().message, HasSubstr("its groups: "));
    EXPECT_THAT(missed.error().message, HasSubstr(", SP,"));
}

}  // namespace
}  // namespace loopwire::device
