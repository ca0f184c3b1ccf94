#include "devices/ac20/ac20_restore_procedure.hpp"

#include <algorithm>
#include <map>

#include <fmt/format.h>

namespace loopwire::device::models {
namespace {

// AC20 configuration menus in menu order ("Menu Conf. 1" .. 6): groups by the lowest address
// of their parameters (2000 Inpt., 2100 Out., 2205 C.Cn., 2300 AC.Cn., 2400 In.Ot., 2500 Othr.).
std::vector<std::string> configuration_menus(const Profile& profile) {
    std::map<std::string, std::uint16_t> lowest;
    for (const Parameter& parameter : profile.parameters) {
        if (!parameter.writable_in("configuration") || !is_restorable(parameter)) continue;
        auto [entry, added] = lowest.emplace(parameter.group, parameter.address);
        if (!added) entry->second = std::min(entry->second, parameter.address);
    }
    std::map<std::uint16_t, std::string> by_address;
    for (const auto& [group, address] : lowest) by_address.emplace(address, group);
    std::vector<std::string> menus;
    for (const auto& [address, group] : by_address) menus.push_back(group);
    return menus;
}

}  // namespace

Result<void> plan_ac20_restore(const Profile& profile, RestorePlan& plan, const RestoreOptions& options, RawValues values) {
    const auto remote = [&] { return procedure_stage("remote (bit 218)", profile, "local_remote", 1); };
    const auto leave = [&] {
        return procedure_stage("control mode (word 3051; the device resets)", profile, "enable_control_mode", 1, ModeEffect::leaves_special_mode);
    };
    plan.stages.push_back(remote());
    const auto configuration = changes_writable_in(plan.changes, "configuration");
    if (!configuration.empty()) {
        plan.stages.push_back(procedure_stage("configuration mode (word 347)", profile, "configuration_mode_code",
                                        options.configuration_lock_code, ModeEffect::enters_special_mode));
        plan.back_to_control = leave().writes.front();
        const auto menus = configuration_menus(profile);
        for (std::size_t index = 0; index < menus.size(); ++index) {
            const std::string& menu = menus[index];
            const std::size_t number = index + 1;
            const auto in_menu = changes_writable_in(configuration, "configuration", menu);
            if (in_menu.empty()) continue;
            auto added = add_value_stage(profile, plan, fmt::format("configuration menu {} ({})", number, menu), in_menu, values);
            if (!added) return added;
            const std::string end = fmt::format("end_configuration_menu_{}", number);
            if (profile.find(end)) plan.stages.push_back(procedure_stage(fmt::format("close menu {} (word {})", number, profile.find(end)->address), profile, end, 1));
        }
        plan.stages.push_back(leave());
        plan.stages.push_back(remote());
    }
    const auto security = changes_writable_in(plan.changes, "security");
    if (!security.empty() && options.include_security) {
        plan.stages.push_back(procedure_stage("security code mode (word 348)", profile, "security_mode_code",
                                        options.configuration_lock_code, ModeEffect::enters_special_mode));
        plan.back_to_control = leave().writes.front();
        if (auto added = add_value_stage(profile, plan, "security-code words", security, values); !added) return added;
        plan.stages.push_back(leave());
        plan.stages.push_back(remote());
    }
    if (options.control_lock_code) {
        plan.stages.push_back(procedure_stage("unlock control parameters (word 349)", profile, "control_lock_code", *options.control_lock_code));
    }
    std::vector<RestoreChange> control;
    for (const RestoreChange& change : plan.changes) {
        if (!change.parameter->writable_in("configuration") && !change.parameter->writable_in("security")) control.push_back(change);
    }
    return add_value_stage(profile, plan, "control parameters", control, values);
}

}  // namespace loopwire::device::models
