#pragma once
// How engineering values are shown: as text for people, as JSON for programs.
#include <string>

#include <nlohmann/json.hpp>

#include "profile/profile.hpp"
#include "profile/values.hpp"

namespace loopwire::device {

// "137.0", "on", "{heating, alarm_1}", "—" for special states (the status says which).
std::string value_text(const Parameter& parameter, const EngineeringValue& value);

// {"value":V,"raw":R,"unit":"°C","status":"ok"}: V a number, a label, an object of named bits,
// or null when the status names a special state. The unit is the value's own (unit_of when read).
nlohmann::ordered_json value_json(const Parameter& parameter, const EngineeringValue& value);

// The unit to show with a value: the one it was decoded with (unit_of), else the parameter's
// fixed unit (values made by hand, e.g. in tests, carry none of their own).
std::string shown_unit(const Parameter& parameter, const EngineeringValue* value);

// "r", "w" or "rw".
std::string access_text(const Parameter& parameter);

}  // namespace loopwire::device
