// What a user names on the command line to profile entries.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <map>

#include "profile/request_planner.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using ::testing::HasSubstr;
using testing::builtin;
using testing::parameter;

std::vector<std::string> names_of(const Result<std::vector<const Parameter*>>& resolved) {
    EXPECT_TRUE(resolved.ok()) << (resolved.ok() ? "" : resolved.error().message);
    std::vector<std::string> names;
    if (resolved.ok()) {
        for (const Parameter* parameter : *resolved) names.push_back(parameter->name);
    }
    return names;
}

std::string error_of(const Result<std::vector<const Parameter*>>& resolved) {
    EXPECT_FALSE(resolved.ok());
    return resolved.ok() ? std::string() : resolved.error().message;
}

TEST(ParameterResolution, NamesThenCaseInsensitiveNamesThenMnemonics) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    EXPECT_EQ(names_of(resolve_parameters(*tc10, {"set_point"})), std::vector<std::string>{"set_point"});
    EXPECT_EQ(names_of(resolve_parameters(*tc10, {"Set_Point"})), std::vector<std::string>{"set_point"});
    EXPECT_EQ(names_of(resolve_parameters(*tc10, {"sp"})), std::vector<std::string>{"set_point"});
    EXPECT_EQ(names_of(resolve_parameters(*tc10, {"SP.LL", "dP"})),
              (std::vector<std::string>{"set_point_low_limit", "decimal_point"}));
}

TEST(ParameterResolution, AmbiguousMnemonicListsTheCandidates) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const std::string message = error_of(resolve_parameters(*tc10, {"ssc"}));
    EXPECT_THAT(message, HasSubstr("mnemonic \"ssc\" is ambiguous"));
    EXPECT_THAT(message, HasSubstr("linear_scale_low (SSC, holding "));
    EXPECT_THAT(message, HasSubstr("output_1_analog_type (SSC, holding 651)"));
}

// PV, SP and OUT on every device, whatever its manual calls them; an alias comes before the
// mnemonics, so the TC10's rV (words 1 and 512) names its primary, word 1 (profile note).
TEST(ParameterResolution, AliasesNameTheSameRolesOnEveryDevice) {
    const std::map<std::string, std::vector<std::string>> expected{
        {"tc10", {"measured_value", "set_point", "output_power"}},
        {"rampsoak", {"process_value", "set_value", "output_percentage"}},
        {"ac20", {"carbon_potential", "main_set_point", "main_output_value"}},
    };
    for (const auto& [id, names] : expected) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile) << id;
        EXPECT_EQ(names_of(resolve_parameters(*profile, {"PV", "SP", "OUT"})), names) << id;
        EXPECT_EQ(names_of(resolve_parameters(*profile, {"pv", "sp", "out"})), names) << id << ", lower case";
    }
    const auto tc10 = builtin("tc10");
    EXPECT_EQ(names_of(resolve_parameters(*tc10, {"rV"})), std::vector<std::string>{"measured_value"});
    EXPECT_EQ(names_of(resolve_parameters(*tc10, {"measured_value_b"})), std::vector<std::string>{"measured_value_b"});
}

TEST(ParameterResolution, GroupsGiveTheirReadableMembersInProfileOrder) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    const auto names = names_of(resolve_parameters(*ac20, {"st.pn"}));
    EXPECT_EQ(names.size(), 6u);
    EXPECT_EQ(names.front(), "main_set_point");
    // Hidden members come when their group is named.
    EXPECT_EQ(names_of(resolve_parameters(*ac20, {"Hidn"})).size(), 5u);
}

TEST(ParameterResolution, GroupPrefixReachesAGroupAMnemonicShadows) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const auto names = names_of(resolve_parameters(*tc10, {"group:SP"}));
    EXPECT_EQ(names.size(), 12u);
    EXPECT_THAT(error_of(resolve_parameters(*tc10, {"group:nope"})), HasSubstr("no group \"nope\""));
}

TEST(ParameterResolution, AllIsEveryReadableEntryExceptHiddenOnes) {
    for (const std::string& id : testing::profile_ids) {
        const auto profile = builtin(id);
        ASSERT_TRUE(profile);
        const auto all = resolve_parameters(*profile, {"all"});
        ASSERT_TRUE(all.ok());
        std::size_t expected = 0;
        for (const Parameter& parameter : profile->parameters) expected += parameter.readable && !parameter.hidden;
        EXPECT_EQ(all->size(), expected) << id;
        for (const Parameter* parameter : *all) EXPECT_TRUE(parameter->readable && !parameter->hidden) << parameter->name;
    }
}

TEST(ParameterResolution, OrderIsKeptAndDuplicatesDropped) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    EXPECT_EQ(names_of(resolve_parameters(*tc10, {"set_point", "decimal_point", "SP"})),
              (std::vector<std::string>{"set_point", "decimal_point"}));
    EXPECT_TRUE(resolve_parameters(*tc10, {}).ok());
}

TEST(ParameterResolution, WriteOnlyParametersResolveByName) {
    const auto ac20 = builtin("ac20");
    ASSERT_TRUE(ac20);
    EXPECT_EQ(names_of(resolve_parameters(*ac20, {"start_probe_test"})), std::vector<std::string>{"start_probe_test"});
}

TEST(ParameterResolution, UnknownNameSaysSoAndSuggests) {
    const auto tc10 = builtin("tc10");
    ASSERT_TRUE(tc10);
    const std::string message = error_of(resolve_parameters(*tc10, {"set_point", "point_low"}));
    EXPECT_THAT(message, HasSubstr("no parameter \"point_low\" on tc10"));
    EXPECT_THAT(message, HasSubstr("did you mean set_point_low_limit"));
}

}  // namespace
}  // namespace loopwire::device
