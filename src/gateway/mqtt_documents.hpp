#pragma once
// What the MQTT front publishes about a parameter besides its value: the /meta document, and
// Home Assistant's discovery document (gateway/mqtt_bridge.hpp). Pure functions of the profile
// and the configuration, kept apart from the network code so that they are tested alone.
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "gateway/gateway_config.hpp"
#include "gateway/value_cache.hpp"
#include "profile/profile.hpp"

namespace loopwire::gateway {

// `text` with every character that is not a letter, digit, '-' or '_' made '_': a topic level
// or an object id with no '/', '+', '#', space or anything else that needs escaping.
std::string sanitized_level(const std::string& text);

// PREFIX/DEVICE/PARAMETER/meta: unit, decimals, writable, min, max, enum labels, mnemonic,
// status, this sample's error and the last error seen (kept until another replaces it).
// `parameter` may be null (a name the profile does not know): then only what the change says.
nlohmann::json meta_document(const ValueChange& change, const device::Parameter* parameter, const std::string& last_error);

// What meta_document is made of from a change, in one string: equal inputs make an equal
// document, so a front can tell a value's change from one that changes its meta without building
// the JSON (most changes are a new value and nothing else).
std::string meta_inputs(const ValueChange& change, const device::Parameter* parameter, const std::string& last_error);

// A discovery document for Home Assistant's MQTT integration ("MQTT discovery"), published
// retained on `topic`.
struct DiscoveryDocument {
    std::string topic;  // DISCOVERY_PREFIX/COMPONENT/GATEWAY_DEVICE_PARAMETER/config
    nlohmann::json config;  // null: the entity is removed (an empty retained payload)
};

// The gateway as Home Assistant's device of its own (identifier: the gateway's name), which every
// controller's device block names as its via_device: a connectivity binary_sensor
// GATEWAY_status on PREFIX/status, with loopwire's version and the dashboard's address
// (configuration_url) when the HTTP front serves one.
DiscoveryDocument gateway_document(const MqttConfig& config);
std::string gateway_device_id(const MqttConfig& config);

// The component that fits the parameter: number (a writable number), select (a writable enum or
// bit), binary_sensor (a read-only bit, or an enum whose labels are on/off), sensor (the rest).
// Writable components only when the configuration takes writes; a read-only view otherwise.
// A configuration parameter (kept across power-off, not the loop's PV, SP or OUT) is in Home
// Assistant's `config` category when commanded, `diagnostic` when only shown.
// `latest`: the parameter's latest value, whose unit and decimals were resolved from the
// device's configuration words where the profile gives none of its own ("°C" or "°F" and the
// decimal point of a TC10's set point); null: the profile's alone. A temperature gets Home
// Assistant's device class `temperature`.
DiscoveryDocument discovery_document(const MqttConfig& config, const std::string& device_name, const device::Profile& profile,
                                     const device::Parameter& parameter, const ValueChange* latest = nullptr);

// One Home Assistant binary_sensor per named bit of a bit field (an alarm or status word), each
// reading its bit from the field's state topic; `problem` class for alarms and errors. Empty
// for any other parameter.
std::vector<DiscoveryDocument> bit_documents(const MqttConfig& config, const std::string& device_name,
                                             const device::Profile& profile, const device::Parameter& parameter);

// The decimals a value shows (device::ResolvedValue::decimals): the profile's fixed ones, else
// those the latest value was read with (set by another parameter, e.g. a decimal-point word), else 0.
int shown_decimals(const device::Parameter& parameter, const ValueChange* latest);

// An entity's name in Home Assistant: the first sentence of the parameter's description (the
// manual's words), else its name when there is none or it is too long for a tile.
std::string friendly_name(const device::Parameter& parameter);

// Home Assistant's device class for a unit: "temperature" for °C, °F and K, the units its
// temperature class takes; empty for the rest (%, %C, mV: no class fits them).
std::string device_class_of(std::string_view unit);

// What a device's control loop looks like from its latest values: the unit of its PV and the
// decimals of its SP (profile aliases PV and SP).
struct ControlLoopSample {
    std::string pv_unit;  // "°C"
    int sp_decimals = 0;  // of the set point's latest text ("150.5": 1)
    bool mode_polled = false;  // the loop's mode word (alias MODE) has a value on its topic
    bool out_polled = false;   // the loop's control output (alias OUT) has a value on its topic
    device::ValueLimits sp_limits = {};  // the set point's limits as the device holds them, where known

    bool operator==(const ControlLoopSample&) const = default;
};

// A Home Assistant `climate` entity for the device's control loop, so a temperature controller
// appears as a thermostat: current temperature from PV, target temperature from SP (commanded
// on SP's /set topic when the configuration takes writes), the step from SP's decimals, the
// limits the device holds for SP (else its profile's fixed ones, else what its word holds); with a polled MODE, the device's modes
// as presets and heat/off from them (commanded on MODE's /set topic). None when the profile names no PV and
// SP, when either is not a number, or when the PV is not a temperature in °C or °F.
std::optional<DiscoveryDocument> climate_document(const MqttConfig& config, const std::string& device_name,
                                                  const device::Profile& profile, const ControlLoopSample& sample);

// Where climate_document's document goes; an empty retained payload there removes the entity
// (a PV whose unit is no longer a temperature).
std::string climate_topic(const MqttConfig& config, const std::string& device_name);

// The profile's PV, SP, MODE and OUT parameters (its aliases), for the loop above; null when it has
// none. MODE is an enumeration of the device's own operating modes (TC10: auto, manual,
// standby): the thermostat's presets, and its on/off (Home Assistant's heat/off) where one of
// them means the loop is not controlling.
struct ControlLoop {
    const device::Parameter* pv = nullptr;
    const device::Parameter* sp = nullptr;
    const device::Parameter* mode = nullptr;
    const device::Parameter* out = nullptr;  // the control output, in %: heating or idle
};
ControlLoop control_loop_of(const device::Profile& profile);

}  // namespace loopwire::gateway
