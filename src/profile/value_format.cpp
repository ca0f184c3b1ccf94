#include "profile/value_format.hpp"

#include <fmt/format.h>

namespace loopwire::device {
namespace {

int shown_decimals(double number) {
    // Values carry at most 4 decimals (schema); show what the number has, no float noise.
    for (int decimals = 0; decimals < 4; ++decimals) {
        const double scaled = number * std::pow(10.0, decimals);
        if (std::abs(scaled - std::round(scaled)) < 1e-6) return decimals;
    }
    return 4;
}

}  // namespace

std::string value_text(const Parameter&, const EngineeringValue& value) {
    if (const auto* number = std::get_if<double>(&value.value)) {
        return fmt::format("{:.{}f}", *number, value.decimals.value_or(shown_decimals(*number)));
    }
    if (const auto* label = std::get_if<std::string>(&value.value)) return *label;
    if (const auto* bits = std::get_if<std::map<std::string, bool>>(&value.value)) {
        std::vector<std::string> set;
        for (const auto& [name, on] : *bits) {
            if (on) set.push_back(name);
        }
        return "{" + fmt::format("{}", fmt::join(set, ", ")) + "}";
    }
    return "-";
}

nlohmann::ordered_json value_json(const Parameter& parameter, const EngineeringValue& value) {
    nlohmann::ordered_json shown = nullptr;
    if (const auto* number = std::get_if<double>(&value.value)) shown = *number;
    else if (const auto* label = std::get_if<std::string>(&value.value)) shown = *label;
    else if (const auto* bits = std::get_if<std::map<std::string, bool>>(&value.value)) shown = *bits;
    return {{"value", shown}, {"raw", value.raw}, {"unit", shown_unit(parameter, &value)}, {"status", value.status}};
}

std::string shown_unit(const Parameter& parameter, const EngineeringValue* value) {
    return value != nullptr && !value->unit.empty() ? value->unit : parameter.unit;
}

std::string access_text(const Parameter& parameter) {
    return std::string(parameter.readable ? "r" : "") + (parameter.writable ? "w" : "");
}

}  // namespace loopwire::device
