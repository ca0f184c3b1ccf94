#pragma once
// How the AC20 takes a saved configuration back (ac20-modbus-jbus-eng824e.en.txt Notes 5-9):
// remote (bit 218) first; configuration parameters in configuration mode (word 347 = the
// configuration lock combination, Note 7), menu by menu, each closed with its end-of-menu word
// 3000-3005 (whose reply reports a congruence error 101-106); security-code words only when
// asked, in security code mode (word 348, Note 8); back to control mode with 1 at word 3051
// (the device resets, so remote again); control parameters last, after unlocking with word 349
// when a control lock combination is given (N.B. after Note 9). Mode-entry and command words
// (347-349, 3000-3051, bits 218 and 223-232) are procedure, never restored as values.
#include "client/restore_plan.hpp"

namespace loopwire::device::models {

// The AC20's client::RestoreProcedure, registered for profile id "ac20" (devices/registry.cpp).
Result<void> plan_ac20_restore(const Profile& profile, RestorePlan& plan, const RestoreOptions& options, RawValues values);

}  // namespace loopwire::device::models
