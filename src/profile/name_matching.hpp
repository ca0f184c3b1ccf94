#pragma once
// How what a user types is compared with the names, mnemonics, aliases and groups of a profile,
// and which of them are offered when nothing matches.
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "profile/profile.hpp"

namespace loopwire::device {

// The text as names are compared: ASCII letters in lower case, and the manuals' non-ASCII
// letters as the ASCII letter a user types for them. The AC20 manual prints the display's
// 7-segment 'm' as 'ñ' ("Alrñ" is the alarm menu, "tiñE" the timers, "ñ.OLL" the main output
// low limit), so 'ñ'/'Ñ' fold to 'm': `m.OLL` names ñ.OLL (profiles/NOTES.md, "ASCII for
// non-ASCII mnemonic letters"). Other bytes are kept as they are.
std::string folded_name(std::string_view text);

// Whether a typed text names `listed`: equal once both are folded.
bool same_name(std::string_view typed, std::string_view listed);

// The optimal string alignment distance between the folded texts: insertions, deletions,
// substitutions and swaps of neighbours count one each ("sett_point" is one from "set_point",
// "SP.HL" one from "SP.LH"). Counted in bytes of the folded texts.
std::size_t edit_distance(std::string_view a, std::string_view b);

// The profile's groups (menus), each once, in the order of their first parameter.
std::vector<std::string> group_names(const Profile& profile);

// Up to `most` entries of `profile` close to `typed`, nearest first, as "name (mnemonic)" (or
// "group NAME"): every parameter is measured by the nearest of its name, mnemonic and aliases,
// every group by its name. Offered are the nearest and those one edit further, all close:
// within a third of the typed length (at least 1, at most 3 edits). When none is
// close, the entries whose words contain the typed text (3 characters or more), in profile order.
std::vector<std::string> nearest_names(const Profile& profile, std::string_view typed, std::size_t most = 3);

}  // namespace loopwire::device
