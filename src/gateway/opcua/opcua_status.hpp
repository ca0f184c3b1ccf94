#pragma once
// What the OPC UA front says of a value, a device and a write, decided once (docs/DESIGN.md,
// "Statuses, one vocabulary"): pure functions of the gateway's words, so that they are tested
// without a server.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "client/device_status.hpp"
#include "common/result.hpp"
#include "profile/profile.hpp"

namespace loopwire::gateway {

// How a parameter is typed in the address space: a number with decimals or a physical unit is
// scaled (AnalogItemType, Double); a whole word without either is Int16 or UInt16; a switch is
// Boolean; an enumeration shows its label (String); a bit field its word (UInt16).
enum class OpcuaDataKind { analog, int16, uint16, boolean, label, bits };
OpcuaDataKind opcua_data_kind(const device::Parameter& parameter);

// A value's status word (ValueChange::status) as a StatusCode: "ok" (and "unknown-label", a
// number without a listed label) Good; "stale" Uncertain_LastUsableValue; "no-reply"
// Bad_NoCommunication; "line-down" Bad_NotConnected; a special state of the profile
// ("under-range", ...) Bad_SensorFailure; "error" Bad_DeviceFailure.
std::uint32_t value_status_code(std::string_view status);

// A device's status before its values are known: waiting Bad_WaitingForInitialData, and the
// rest as value_status_code says them (ok and partial Good, wrong-device Bad_ConfigurationError).
std::uint32_t device_status_code(device::DeviceStatus status);

// A write the device writer refused or failed: refused before it was sent because the device
// is silent or its line down (`unsent`) Bad_NoCommunication; a timeout Bad_Timeout; no path to
// the device Bad_NoCommunication; the profile's checks (range, decimals, mode) Bad_OutOfRange;
// an exception reply: 02h Bad_NotWritable, 03h Bad_OutOfRange, others Bad_DeviceFailure.
std::uint32_t write_error_code(const Error& error, bool unsent);

// The UNECE Recommendation 20 common code of a unit (°C CEL, °F FAH, % P1, s SEC, ...) and
// its UnitId as OPC UA Part 8 encodes it (the code's characters, 8 bits each); none for a unit
// without one.
struct UneceUnit {
    std::string code;
    std::int32_t unit_id = -1;
};
std::optional<UneceUnit> unece_unit(std::string_view unit);

}  // namespace loopwire::gateway
