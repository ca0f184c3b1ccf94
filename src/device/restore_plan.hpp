#pragma once
// How to put a saved configuration (a `loopwire dump`) back into a device: which writable
// parameters differ, and the stages that write them in the order and the modes the manual
// requires. Planning only; restore_command.cpp runs the stages and verifies them.
//
// Generic order: within a stage, a value goes in only once the values it is bounded by allow
// it (TC10: a new SP above the present SP.HL waits for the new SP.HL), found by trying the
// pending writes against the device's values as they will be at that point.
//
// AC20 (ac20-modbus-jbus-eng824e.en.txt Notes 5-9): remote (bit 218) first; configuration
// parameters in configuration mode (word 347 = the configuration lock combination, Note 7),
// menu by menu, each closed with its end-of-menu word 3000-3005 (whose reply reports a
// congruence error 101-106); security-code words only when asked, in security code mode
// (word 348, Note 8); back to control mode with 1 at word 3051 (the device resets, so remote
// again); control parameters last, after unlocking with word 349 when a control lock
// combination is given (N.B. after Note 9). Mode-entry and command words (347-349, 3000-3051,
// bits 218 and 223-232) are procedure, never restored as values.
#include <optional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "device/profile.hpp"
#include "device/request_planner.hpp"
#include "device/values.hpp"

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

// `saved`: the dump's raw words by name; `current`: the device's words now (every writable
// parameter of the dump must be there). Errors name a parameter the profile lacks, or
// bounds that cannot be satisfied in any order.
Result<RestorePlan> plan_restore(const Profile& profile, const RawValues& saved, const RawValues& current,
                                 const RestoreOptions& options);

}  // namespace loopwire::device
