#pragma once
// From a profile document that passed the schema and the checks of profile_checks.hpp to the
// structs of profile.hpp.
#include <nlohmann/json.hpp>

#include "profile/profile.hpp"

namespace loopwire::device {

// word_specials (schema: "hold for every word of the device unless a parameter says
// otherwise") are appended to every holding/input entry's own special values, after them, so
// a decoder that takes the first match lets the parameter's own meaning win.
Profile profile_from_document(const nlohmann::json& document);

}  // namespace loopwire::device
