#include "client/resolved_value.hpp"

#include <cmath>

#include "profile/value_format.hpp"

namespace loopwire::device {
namespace {

// limits_of, with the one fallback for a bound in display counts whose decimals word was not
// read with the value: the decimals the value itself carries.
ValueLimits shown_limits(const Parameter& parameter, const EngineeringValue* value, const RawValues& known) {
    ValueLimits limits = limits_of(parameter, known);
    if (!parameter.range_in_counts || !value || !value->decimals) return limits;
    const auto scaled = [&](const std::optional<Bound>& bound, std::optional<double>& limit) {
        const double* counts = bound ? std::get_if<double>(&*bound) : nullptr;
        if (!limit && counts) limit = *counts / std::pow(10.0, *value->decimals);
    };
    scaled(parameter.min, limits.min);
    scaled(parameter.max, limits.max);
    return limits;
}

}  // namespace

std::optional<std::string> bounding_parameter(const std::optional<Bound>& bound) {
    const auto* name = bound ? std::get_if<std::string>(&*bound) : nullptr;
    return name ? std::optional<std::string>(*name) : std::nullopt;
}

int shown_decimals(const Parameter& parameter, const EngineeringValue* value) {
    if (const int* fixed = std::get_if<int>(&parameter.decimals)) return *fixed;
    return value && value->decimals ? *value->decimals : 0;
}

ResolvedValue resolve_value(const Parameter& parameter, const EngineeringValue* value, const RawValues& known,
                            std::string error) {
    ResolvedValue resolved;
    resolved.limits = shown_limits(parameter, value, known);
    resolved.decimals = shown_decimals(parameter, value);
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

ResolvedValue resolve_watched(const WatchedDevice& device, const WatchedValue& value, MonitorClock::time_point now) {
    ResolvedValue resolved = resolve_value(*value.parameter, value.last ? &*value.last : nullptr, device.known,
                                           value.fresh ? std::string() : value.error);
    resolved.status = value_status(device, value);
    if (!value.fresh) resolved.error = value.error;
    resolved.age = age_seconds(value, now);
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
