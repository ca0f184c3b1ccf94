#pragma once
// What the MQTT front publishes about a parameter besides its value: the /meta document, and
// Home Assistant's discovery document (gateway/mqtt_bridge.hpp). Pure functions of the profile
// and the configuration, kept apart from the network code so that they are tested alone.
#include <string>

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

// A discovery document for Home Assistant's MQTT integration ("MQTT discovery"), published
// retained on `topic`.
struct DiscoveryDocument {
    std::string topic;  // DISCOVERY_PREFIX/COMPONENT/GATEWAY_DEVICE_PARAMETER/config
    nlohmann::json config;
};

// The component that fits the parameter: number (a writable number), select (a writable enum or
// bit), binary_sensor (a read-only bit, or an enum whose labels are on/off), sensor (the rest).
// Writable components only when the configuration takes writes; a read-only view otherwise.
DiscoveryDocument discovery_document(const MqttConfig& config, const std::string& device_name, const device::Profile& profile,
                                     const device::Parameter& parameter);

}  // namespace loopwire::gateway
