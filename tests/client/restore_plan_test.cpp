// Restore planning (client/restore_plan.hpp; the AC20 procedure of devices/ac20): what differs, and the order and modes the
// manuals require for writing it back.
#include <gtest/gtest.h>

#include "simulation/device_memory.hpp"
#include "client/restore_plan.hpp"
#include "devices/registry.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using testing::builtin;

// A device's words at power-on, by name (the simulator's defaults), as `current`.
RawValues defaults_of(const std::shared_ptr<const Profile>& profile) {
    DeviceMemory memory(profile);
    RawValues values;
    for (const Parameter& parameter : profile->parameters) {
        if (const MemoryCell* cell = memory.cell(parameter.name)) values[parameter.name] = cell->raw;
    }
    return values;
}

std::vector<std::string> titles(const RestorePlan& plan) {
    std::vector<std::string> result;
    for (const auto& stage : plan.stages) result.push_back(stage.title);
    return result;
}

std::vector<std::string> written_names(const RestorePlan& plan) {
    std::vector<std::string> names;
    for (const auto& stage : plan.stages) {
        for (const auto& write : stage.writes) names.push_back(write.parameter->name);
    }
    return names;
}

// TC10 §5.3.8: SP lies within SP.LL..SP.HL. Lowering SP.HL below the present SP must wait for
// the new SP; raising SP above the present SP.HL must wait for the new SP.HL.
TEST(RestorePlan, Tc10WritesBoundsAndBoundedValuesInAnOrderThatNeverViolatesThem_Section5_3_8) {
    auto tc10 = builtin("tc10");
    RawValues current = defaults_of(tc10);
    current["set_point_low_limit"] = 0;
    current["set_point_high_limit"] = 500;
    current["set_point"] = 400;
    RawValues lowered = current;
    lowered["set_point_high_limit"] = 300;
    lowered["set_point"] = 250;
    auto plan = plan_restore(*tc10, lowered, current, {});
    ASSERT_TRUE(plan) << plan.error().message;
    EXPECT_EQ(written_names(*plan), (std::vector<std::string>{"set_point", "set_point_high_limit"}));
    RawValues raised = current;
    raised["set_point_high_limit"] = 900;
    raised["set_point"] = 800;
    plan = plan_restore(*tc10, raised, current, {});
    ASSERT_TRUE(plan) << plan.error().message;
    EXPECT_EQ(written_names(*plan), (std::vector<std::string>{"set_point_high_limit", "set_point"}));
}

TEST(RestorePlan, ValuesOutsideTheirBoundsInAnyOrderAreRefusedNamingThem) {
    auto tc10 = builtin("tc10");
    RawValues current = defaults_of(tc10);
    RawValues impossible = current;
    impossible["set_point_low_limit"] = 500;
    impossible["set_point_high_limit"] = 600;
    impossible["set_point"] = 700;
    auto plan = plan_restore(*tc10, impossible, current, {});
    ASSERT_FALSE(plan);
    EXPECT_NE(plan.error().message.find("set_point"), std::string::npos) << plan.error().message;
}

TEST(RestorePlan, NothingDiffersNothingPlanned) {
    auto tc10 = builtin("tc10");
    const RawValues current = defaults_of(tc10);
    auto plan = plan_restore(*tc10, current, current, {});
    ASSERT_TRUE(plan);
    EXPECT_TRUE(plan->changes.empty());
    EXPECT_TRUE(plan->stages.empty());
}

TEST(RestorePlan, ANameTheProfileLacksIsAnError) {
    auto tc10 = builtin("tc10");
    const RawValues current = defaults_of(tc10);
    auto plan = plan_restore(*tc10, {{"carbon_potential", 3}}, current, {});
    ASSERT_FALSE(plan);
    EXPECT_NE(plan.error().message.find("carbon_potential"), std::string::npos);
}

// AC20 Notes 5-9: remote; configuration mode (347); menus in order, each closed (3000-3005);
// back to control mode (3051, the device resets); remote again; control parameters.
TEST(RestorePlan, Ac20FollowsRemoteConfigurationMenusControlModeOrder_Notes5To9) {
    auto ac20 = builtin("ac20");
    RawValues current = defaults_of(ac20);
    RawValues saved = current;
    const Parameter* output_menu = nullptr;  // a configuration word of menu 2 (Out., 2100..)
    const Parameter* input_menu = nullptr;   // and one of menu 1 (Inpt., 2000..)
    for (const Parameter& p : ac20->parameters) {
        if (!p.writable || !p.readable || p.write_modes != std::vector<std::string>{"configuration"}) continue;
        if (p.group == "Out." && !output_menu) output_menu = &p;
        if (p.group == "Inpt." && !input_menu && p.type == ValueType::enumeration && p.enum_labels.size() > 1) input_menu = &p;
    }
    ASSERT_TRUE(output_menu && input_menu);
    auto other_label = [&](const Parameter& p) {
        for (const auto& [code, label] : p.enum_labels) if (static_cast<std::uint16_t>(code) != current[p.name]) return static_cast<std::uint16_t>(code);
        return current[p.name];
    };
    saved[input_menu->name] = other_label(*input_menu);
    saved[output_menu->name] = output_menu->type == ValueType::enumeration ? other_label(*output_menu) : static_cast<std::uint16_t>(current[output_menu->name] + 1);
    saved["main_set_point"] = static_cast<std::uint16_t>(current["main_set_point"] + 10);
    saved["configuration_mode_code"] = 7;  // a mode-entry word: procedure, never a value
    RestoreOptions options;
    options.configuration_lock_code = 42;
    auto plan = plan_restore(*ac20, saved, current, options, models::restore_procedure_for(*ac20));
    ASSERT_TRUE(plan) << plan.error().message;
    EXPECT_EQ(plan->changes.size(), 3U);
    EXPECT_EQ(titles(*plan), (std::vector<std::string>{
                                 "remote (bit 218)", "configuration mode (word 347)",
                                 "configuration menu 1 (Inpt.)", "close menu 1 (word 3000)",
                                 "configuration menu 2 (Out.)", "close menu 2 (word 3001)",
                                 "control mode (word 3051; the device resets)", "remote (bit 218)",
                                 "control parameters"}));
    EXPECT_EQ(plan->stages[1].writes.front().raw, 42);
    ASSERT_TRUE(plan->back_to_control);
    EXPECT_EQ(plan->back_to_control->parameter->address, 3051);
}

TEST(RestorePlan, Ac20SecurityWordsOnlyWhenAskedInSecurityCodeMode_Note8) {
    auto ac20 = builtin("ac20");
    RawValues current = defaults_of(ac20);
    RawValues saved = current;
    saved["control_lock_combination"] = 77;
    auto plan = plan_restore(*ac20, saved, current, {}, models::restore_procedure_for(*ac20));
    ASSERT_TRUE(plan);
    EXPECT_TRUE(plan->changes.empty());
    ASSERT_EQ(plan->skipped.size(), 1U);
    RestoreOptions options;
    options.include_security = true;
    plan = plan_restore(*ac20, saved, current, options, models::restore_procedure_for(*ac20));
    ASSERT_TRUE(plan);
    EXPECT_EQ(titles(*plan), (std::vector<std::string>{"remote (bit 218)", "security code mode (word 348)",
                                                        "security-code words", "control mode (word 3051; the device resets)",
                                                        "remote (bit 218)"}));
}

}  // namespace
}  // namespace loopwire::device
