#pragma once
// How to put a saved configuration (a `loopwire dump`) back into a device: which writable
// parameters differ, and the stages that write them in the order and the modes the manual
// requires. Planning only; restore_command.cpp runs the stages and verifies them.
//
// Generic order: within a stage, a value goes in only once the values it is bounded by allow
// it (TC10: a new SP above the present SP.HL waits for the new SP.HL), found by trying the
// pending writes against the device's values as they will be at that point.
//
// A device whose manual prescribes modes and an order (the AC20's configuration procedure,
// devices/ac20/ac20_restore_procedure.cpp) brings its own RestoreProcedure, found in the
// device registry (devices/registry.hpp) by profile id; the building blocks below are for it.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "profile/profile.hpp"
#include "profile/request_planner.hpp"
#include "profile/values.hpp"

namespace loopwire::device {

// Whether restore writes `parameter` back: stored (profile "storage": "persistent"), readable
// and writable, and not a procedure word (see restore_plan.cpp).
bool is_restorable(const Parameter& parameter);

struct RestoreChange {
    const Parameter* parameter = nullptr;
    std::uint16_t from = 0;
    std::uint16_t to = 0;
};

// What a stage does to the AC20's mode: what must be undone if a later stage fails.
enum class ModeEffect { none, enters_special_mode /* 347/348 */, leaves_special_mode /* 3051 */ };

struct RestoreStage {
    std::string title;                  // "configuration menu 1 (Inpt.)", "control parameters"
    std::vector<PlannedWrite> writes;   // sent one after another, in this order
    bool restores_values = false;       // false: mode changes and commands (not verified)
    ModeEffect mode_effect = ModeEffect::none;
};

struct RestorePlan {
    std::vector<RestoreChange> changes;  // what differs, in profile order
    std::vector<RestoreStage> stages;
    std::vector<std::string> skipped;    // differing parameters not restored, with the reason
    // The write that returns the device to control mode (AC20 3051 = 1), when the plan leaves
    // it; sent after a failure inside configuration or security-code mode.
    std::optional<PlannedWrite> back_to_control;
};

struct RestoreOptions {
    bool include_security = false;               // AC20 security-code words 4000-4011
    std::uint16_t configuration_lock_code = 0;   // AC20 word 347/348 value (Note 7 *: 0 = any)
    std::optional<std::uint16_t> control_lock_code;  // AC20 word 349 value, if the device is locked
};

// A device's own order of restoring: fills plan.stages (and back_to_control) from
// plan.changes, given the device's values now.
using RestoreProcedure =
    std::function<Result<void>(const Profile& profile, RestorePlan& plan, const RestoreOptions& options, RawValues current)>;

// `saved`: the dump's raw words by name; `current`: the device's words now (every writable
// parameter of the dump must be there). Without a procedure the changes are written in one
// stage, in an order that keeps every bound. Errors name a parameter the profile lacks, or
// bounds that cannot be satisfied in any order.
Result<RestorePlan> plan_restore(const Profile& profile, const RawValues& saved, const RawValues& current,
                                 const RestoreOptions& options, const RestoreProcedure& procedure = {});

// Building blocks of procedures.
// A stage of procedure: one command word (`name` = `raw`), not a restored value.
RestoreStage procedure_stage(std::string title, const Profile& profile, std::string_view name, std::uint16_t raw,
                             ModeEffect effect = ModeEffect::none);
// The changes writable in `mode`, and in `group` when one is given.
std::vector<RestoreChange> changes_writable_in(const std::vector<RestoreChange>& changes, std::string_view mode,
                                               std::string_view group = {});
// Appends a stage writing `changes` in a bound-safe order; `values` then holds them.
Result<void> add_value_stage(const Profile& profile, RestorePlan& plan, std::string title,
                             const std::vector<RestoreChange>& changes, RawValues& values);

}  // namespace loopwire::device
