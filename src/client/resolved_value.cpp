#include "client/resolved_value.hpp"

#include "profile/value_format.hpp"

namespace loopwire::device {

ResolvedValue resolve_value(const Parameter& parameter, const EngineeringValue* value, const RawValues& known,
                            std::string error) {
    ResolvedValue resolved;
    resolved.limits = limits_of(parameter, known);
    if (value == nullptr) {
        // Not read: the unit is still the configuration's when its word was read beside it.
        resolved.unit = unit_of(parameter, known);
        resolved.error = std::move(error);
        return resolved;
    }
    if (const auto* number = std::get_if<double>(&value->value)) resolved.number = *number;
    resolved.text = value_text(parameter, *value);
    resolved.unit = shown_unit(parameter, value);
    resolved.status = value->status;
    resolved.raw = value->raw;
    return resolved;
}

nlohmann::ordered_json resolved_json(const Parameter& parameter, const EngineeringValue* value, const ResolvedValue& resolved) {
    const auto optional_number = [](const std::optional<double>& n) { return n ? nlohmann::ordered_json(*n) : nlohmann::ordered_json(); };
    nlohmann::ordered_json out;
    if (value != nullptr) {
        out = value_json(parameter, *value);  // value, raw, unit, status as before
        out["text"] = resolved.text;
    } else {
        out = {{"value", nullptr}, {"raw", nullptr}, {"unit", resolved.unit}, {"status", resolved.status}, {"error", resolved.error}};
    }
    out["min"] = optional_number(resolved.limits.min);
    out["max"] = optional_number(resolved.limits.max);
    return out;
}

}  // namespace loopwire::device
