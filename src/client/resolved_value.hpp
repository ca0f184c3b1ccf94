#pragma once
// One parameter's value as every front shows it: the command line, the
// public library and the gateway's HTTP API resolve a reading through this one function, so they
// cannot disagree on its text, its unit or its limits.
#include <cstdint>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "client/device_client.hpp"
#include "profile/values.hpp"

namespace loopwire::device {

struct ResolvedValue {
    std::optional<double> number;  // in engineering units, when the value is a number
    // With the decimals the device gave it ("425.0", "0.85"), a label, the set bits, or "—"
    // for a special state; empty when the read failed.
    std::string text;
    // The unit the device's configuration gives it (a TC10's °C or °F from its unit word), not
    // the profile's default; "?" when the word it follows was not read.
    std::string unit;
    // In engineering units as the device holds them now: a fixed bound scaled by the present
    // decimals, or the value of the parameter that bounds it (SP between SP.LL and SP.HL).
    ValueLimits limits;
    std::string status = "error";  // "ok", a special state ("under-range", ...), or "error"
    std::string error;             // why the read failed, when status is "error"
    std::optional<std::uint16_t> raw;
};

// `value` null for a read that failed (`error` says why). `known` holds the words read with it
// (decimals, unit and bounding words: DeviceClient::read reads them as dependencies).
ResolvedValue resolve_value(const Parameter& parameter, const EngineeringValue* value, const RawValues& known,
                            std::string error = {});

inline ResolvedValue resolve_reading(const ParameterReading& reading, const RawValues& known) {
    return resolve_value(*reading.parameter, reading.value ? &*reading.value : nullptr, known, reading.error);
}

// {"value":V,"text":"425.0","unit":"°C","min":0,"max":1000,"status":"ok","raw":R} (+ "error"):
// what `read --json` prints for each value.
nlohmann::ordered_json resolved_json(const Parameter& parameter, const EngineeringValue* value, const ResolvedValue& resolved);

}  // namespace loopwire::device
