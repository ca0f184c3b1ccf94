#include "client/restore_plan.hpp"

#include <algorithm>
#include <map>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

bool bounded_by(const Parameter& parameter, const std::string& name) {
    const auto names = [&](const std::optional<Bound>& bound) {
        const std::string* bound_name = bound ? std::get_if<std::string>(&*bound) : nullptr;
        return bound_name != nullptr && *bound_name == name;
    };
    return names(parameter.min) || names(parameter.max);
}

// Whether writing `change` now keeps it, and every value it bounds, within range.
bool keeps_ranges(const Profile& profile, const RestoreChange& change, const RawValues& values, bool strict) {
    if (!raw_in_range(*change.parameter, change.to, values)) return false;
    if (!strict) return true;
    RawValues after = values;
    after[change.parameter->name] = change.to;
    return std::all_of(profile.parameters.begin(), profile.parameters.end(), [&](const Parameter& other) {
        const auto value = after.find(other.name);
        return !bounded_by(other, change.parameter->name) || value == after.end() ||
               raw_in_range(other, value->second, after);
    });
}

// Orders `changes` so each value is within its bounds when it is written, given the values
// written before it, and preferably so the values it bounds stay within range too (TC10: a
// lower SP.HL waits for the lower SP). A set no order can satisfy is an error naming them.
Result<std::vector<PlannedWrite>> bound_safe_order(const Profile& profile, std::vector<RestoreChange> changes, RawValues values) {
    std::vector<PlannedWrite> ordered;
    while (!changes.empty()) {
        auto next = std::find_if(changes.begin(), changes.end(),
                                 [&](const RestoreChange& change) { return keeps_ranges(profile, change, values, true); });
        if (next == changes.end()) {
            next = std::find_if(changes.begin(), changes.end(),
                                [&](const RestoreChange& change) { return keeps_ranges(profile, change, values, false); });
        }
        if (next == changes.end()) {
            std::vector<std::string> names;
            for (const RestoreChange& change : changes) names.push_back(change.parameter->name);
            return make_error(ErrorKind::usage, fmt::format("the saved values of {} are outside the ranges their bounds "
                                                            "allow in any order of writing; check the dump file",
                                                            fmt::join(names, ", ")));
        }
        values[next->parameter->name] = next->to;
        ordered.push_back({next->parameter, next->to});
        changes.erase(next);
    }
    return ordered;
}

}  // namespace

// A stage of procedure: one command word, not a restored value.
RestoreStage procedure_stage(std::string title, const Profile& profile, std::string_view name, std::uint16_t raw,
                       ModeEffect effect) {
    return RestoreStage{std::move(title), {PlannedWrite{profile.find(name), raw}}, false, effect};
}

std::vector<RestoreChange> changes_writable_in(const std::vector<RestoreChange>& changes, std::string_view mode,
                                  std::string_view group) {
    std::vector<RestoreChange> selected;
    for (const RestoreChange& change : changes) {
        if (change.parameter->writable_in(mode) && (group.empty() || change.parameter->group == group)) selected.push_back(change);
    }
    return selected;
}

Result<void> add_value_stage(const Profile& profile, RestorePlan& plan, std::string title, const std::vector<RestoreChange>& changes, RawValues& values) {
    if (changes.empty()) return {};
    auto ordered = bound_safe_order(profile, changes, values);
    if (!ordered) return ordered.error();
    for (const PlannedWrite& write : *ordered) values[write.parameter->name] = write.raw;
    plan.stages.push_back({std::move(title), std::move(*ordered), true, ModeEffect::none});
    return {};
}


// Write-only words are commands (AC20 3000-3051, load-default bits 223-232) and words whose
// only write mode is remote/local are mode switches (AC20 218, 347-349): procedure, not values.
// A dump is a saved configuration: only what the device itself keeps across power-off
// (profile "storage": "persistent") is restored. Live words are not: the AC20 outputs 130-132
// (Table "control non-parameters", no storage; refused with error 10 in automatic), TC10
// remote set point and output overrides (RAM), commands such as TC10 alarm reset.
bool is_restorable(const Parameter& parameter) {
    if (!parameter.writable || !parameter.readable || !parameter.persistent) return false;
    return std::any_of(parameter.write_modes.begin(), parameter.write_modes.end(),
                       [](const std::string& mode) { return mode != "local" && mode != "remote"; }) ||
           parameter.write_modes.empty();
}

Result<RestorePlan> plan_restore(const Profile& profile, const RawValues& saved, const RawValues& current,
                                 const RestoreOptions& options, const RestoreProcedure& procedure) {
    RestorePlan plan;
    for (const auto& [name, raw] : saved) {
        if (!profile.find(name)) return make_error(ErrorKind::usage, fmt::format("the dump names '{}', which {} does not have", name, profile.id));
    }
    for (const Parameter& parameter : profile.parameters) {
        const auto wanted = saved.find(parameter.name);
        if (wanted == saved.end() || !is_restorable(parameter)) continue;
        const auto now = current.find(parameter.name);
        if (now == current.end()) {
            return make_error(ErrorKind::link, fmt::format("{} could not be read from the device, so it cannot be compared", parameter.name));
        }
        if (now->second == wanted->second) continue;
        if (parameter.writable_in("security") && !options.include_security) {
            plan.skipped.push_back(fmt::format("{}: security-code word (give --security to restore it)", parameter.name));
            continue;
        }
        plan.changes.push_back({&parameter, now->second, wanted->second});
    }
    if (plan.changes.empty()) return plan;
    if (procedure) {
        if (auto planned = procedure(profile, plan, options, current); !planned) return planned.error();
        return plan;
    }
    RawValues values = current;
    if (auto added = add_value_stage(profile, plan, "parameters", plan.changes, values); !added) return added.error();
    return plan;
}

}  // namespace loopwire::device
