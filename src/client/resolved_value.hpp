#pragma once
// One parameter's value as every front shows it: the command line, the public library and
// every front of the gateway (HTTP API and dashboard, MQTT and Home Assistant, Sparkplug,
// /metrics, the history) resolve a reading through these functions, so they cannot disagree on
// its text, decimals, unit, limits, status or age, and none has to parse a text back.
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "client/device_client.hpp"
#include "client/monitor_state.hpp"
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
    // The digits after the point its text shows: the profile's fixed decimals, else those the
    // device gave this value (its decimal-point word), else 0 (not read yet).
    int decimals = 0;
    // In engineering units as the device holds them now: a fixed bound scaled by the present
    // decimals, or the value of the parameter that bounds it (SP between SP.LL and SP.HL).
    // The one fallback, where that is not known: a fixed bound in display counts is scaled by
    // the value's own decimals; a bound set by a parameter not read yet is none. Every front
    // shows these numbers, or nothing.
    ValueLimits limits;
    // "ok", a special state ("under-range", ...), or "error"; for a polled value
    // (resolve_watched), also "stale", "no-reply", "line-down": device::value_status.
    std::string status = "error";
    std::string error;  // why the read failed, when status is "error"
    std::optional<std::uint16_t> raw;
    // A polled value's (resolve_watched): seconds since it was read, on the clock the polls
    // run on, as of the moment the view was taken; none before its first read.
    std::optional<double> age;
};

// For a limit the view has no number for: the name of the parameter that sets it, which a front
// may show instead (the HTTP API and MQTT's meta say {"parameter": NAME}); none for a fixed bound
// or no bound. Never a number: every number a front shows for a limit is the view's.
std::optional<std::string> bounding_parameter(const std::optional<Bound>& bound);

// Its `decimals` (above): the profile's fixed ones, else the value's own, else 0.
int shown_decimals(const Parameter& parameter, const EngineeringValue* value);

// `value` null for a read that failed (`error` says why). `known` holds the words read with it
// (decimals, unit and bounding words: DeviceClient::read reads them as dependencies).
ResolvedValue resolve_value(const Parameter& parameter, const EngineeringValue* value, const RawValues& known,
                            std::string error = {});

inline ResolvedValue resolve_reading(const ParameterReading& reading, const RawValues& known) {
    return resolve_value(*reading.parameter, reading.value ? &*reading.value : nullptr, known, reading.error);
}

// A polled value (the monitor's, the gateway's value cache's): the value last read, its status
// as every front says it (device::value_status: a value not read in the device's latest poll
// says why), and its age at `now`, on the clock the polls stamped it with. The text and number
// stay the last value read, for a front that shows it beside its status.
ResolvedValue resolve_watched(const WatchedDevice& device, const WatchedValue& value, MonitorClock::time_point now);

// {"value":V,"text":"425.0","unit":"°C","min":0,"max":1000,"status":"ok","raw":R} (+ "error"):
// what `read --json` prints for each value.
nlohmann::ordered_json resolved_json(const Parameter& parameter, const EngineeringValue* value, const ResolvedValue& resolved);

}  // namespace loopwire::device
