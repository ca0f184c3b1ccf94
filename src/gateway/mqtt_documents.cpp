#include "gateway/mqtt_documents.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <optional>
#include <string_view>

#include <fmt/format.h>
#include <loopwire/version.hpp>

#include "client/resolved_value.hpp"

namespace loopwire::gateway {
namespace {

bool level_character(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '_';
}

nlohmann::json decimals_json(const device::Parameter& parameter) {
    if (const int* fixed = std::get_if<int>(&parameter.decimals)) return *fixed;
    return nlohmann::json{{"parameter", std::get<std::string>(parameter.decimals)}};
}

bool two_state_labels(const device::Parameter& parameter, std::string& on, std::string& off) {
    if (parameter.type == device::ValueType::boolean) {
        const auto one = parameter.enum_labels.find(1);
        const auto zero = parameter.enum_labels.find(0);
        on = one != parameter.enum_labels.end() ? one->second : "1";
        off = zero != parameter.enum_labels.end() ? zero->second : "0";
        return true;
    }
    if (parameter.type != device::ValueType::enumeration || parameter.enum_labels.size() != 2) return false;
    const auto one = parameter.enum_labels.find(1);
    const auto zero = parameter.enum_labels.find(0);
    if (one == parameter.enum_labels.end() || zero == parameter.enum_labels.end()) return false;
    if (one->second != "on" || zero->second != "off") return false;  // a two-way choice, not a state
    on = one->second;
    off = zero->second;
    return true;
}

std::vector<std::string> labels_of(const device::Parameter& parameter) {
    std::vector<std::string> labels;
    for (const auto& [code, label] : parameter.enum_labels) labels.push_back(label);
    return labels;
}

// A number's limits for Home Assistant: only the value's own (device::ResolvedValue::limits, the
// ones every front shows: the profile's range, or the words that bound it once read). Where
// there are none the keys are left out and Home Assistant uses its defaults: what the word can
// hold (-3276.8 .. 3276.7 % for an output) would be a slider nobody can use, and the device
// still refuses what it does not take, which set/result says.
void put_limits(nlohmann::json& doc, const device::ValueLimits& limits, const char* min_key, const char* max_key) {
    if (limits.min) doc[min_key] = *limits.min;
    if (limits.max) doc[max_key] = *limits.max;
    // Home Assistant refuses a document whose minimum is not below its maximum (limit words
    // read while someone moves them): the pair is left out rather than the entity lost.
    if (limits.min && limits.max && !(*limits.min < *limits.max)) {
        doc.erase(min_key);
        doc.erase(max_key);
    }
}

// Home Assistant's entity categories: `config` for an entity that changes how the device is set
// up, `diagnostic` for one that only shows it (HA refuses `config` on a sensor). A parameter
// kept across power-off (the manuals' configuration menus) is one, unless it is the control
// loop's PV, SP, OUT or MODE, which are what the device is for.
std::optional<std::string> entity_category_of(const device::Profile& profile, const device::Parameter& parameter,
                                              bool commanded) {
    if (!parameter.persistent) return std::nullopt;
    for (const char* primary : {"PV", "SP", "OUT", "MODE"}) {
        const auto alias = profile.aliases.find(primary);
        if (alias != profile.aliases.end() && alias->second == parameter.name) return std::nullopt;
    }
    return commanded ? "config" : "diagnostic";
}

// Bits whose name says something is wrong are Home Assistant's `problem` class (on = problem).
bool names_a_problem(std::string name) {
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    for (const char* word : {"alarm", "error", "fail", "break", "overload"}) {
        if (name.find(word) != std::string::npos) return true;
    }
    return false;
}

}  // namespace

std::string sanitized_level(const std::string& text) {
    std::string level = text;
    std::replace_if(level.begin(), level.end(), [](char c) { return !level_character(c); }, '_');
    return level.empty() ? "_" : level;
}

nlohmann::json meta_document(const ValueChange& change, const device::Parameter* parameter, const std::string& last_error) {
    nlohmann::json meta{{"unit", change.unit}, {"status", change.status}, {"error", change.error}, {"last_error", last_error}};
    if (!parameter) return meta;
    meta["mnemonic"] = parameter->mnemonic;
    meta["decimals"] = decimals_json(*parameter);
    // Set by another parameter: the sample's own, when it holds a number.
    if (meta["decimals"].is_object() && change.value && std::holds_alternative<double>(change.value->value)) {
        meta["decimals"] = change.decimals;
    }
    meta["writable"] = parameter->writable;
    // As every front gives them (device::ResolvedValue::limits), else the name of the parameter
    // that sets one (not read yet), else null.
    const auto limit = [](const std::optional<double>& value, const std::optional<device::Bound>& bound) {
        if (value) return nlohmann::json(*value);
        if (auto name = device::bounding_parameter(bound)) return nlohmann::json{{"parameter", *name}};
        return nlohmann::json(nullptr);
    };
    meta["min"] = limit(change.limits.min, parameter->min);
    meta["max"] = limit(change.limits.max, parameter->max);
    nlohmann::json labels = nlohmann::json::object();
    for (const auto& [code, label] : parameter->enum_labels) labels[std::to_string(code)] = label;
    meta["enum"] = std::move(labels);
    return meta;
}

std::string meta_inputs(const ValueChange& change, const device::Parameter* parameter, const std::string& last_error) {
    // As meta_document reads them: without a parameter only what the change says; with one, the
    // parameter (the same for every change of a topic), the limits, and of the value only the
    // decimals its text shows when another parameter sets them.
    const std::string said = fmt::format("{}\x1f{}\x1f{}\x1f{}", change.unit, change.status, change.error, last_error);
    if (!parameter) return said;
    const auto bound = [](const std::optional<double>& value) { return value ? fmt::format("{}", *value) : std::string("-"); };
    const bool decimals_from_text = !std::holds_alternative<int>(parameter->decimals) && change.value &&
                                    std::holds_alternative<double>(change.value->value);
    return fmt::format("{}\x1f{}\x1f{}\x1f{}", said, decimals_from_text ? change.decimals : -1,
                       bound(change.limits.min), bound(change.limits.max));
}

int shown_decimals(const device::Parameter& parameter, const ValueChange* latest) {
    return latest ? latest->decimals : device::shown_decimals(parameter, nullptr);
}

std::string friendly_name(const device::Parameter& parameter) {
    // The description's first sentence ("Measured value (rV)", "Main set point"): what the
    // manual calls it; the rest of it is detail a dashboard tile has no room for.
    std::string_view text = parameter.description;
    text = text.substr(0, std::min(text.find(". "), text.size()));
    while (!text.empty() && (text.back() == '.' || text.back() == ' ')) text.remove_suffix(1);
    constexpr std::size_t longest = 48;
    return text.empty() || text.size() > longest ? parameter.name : std::string(text);
}

std::string device_class_of(std::string_view unit) {
    return unit == "°C" || unit == "°F" || unit == "K" ? "temperature" : "";
}

ControlLoop control_loop_of(const device::Profile& profile) {
    const auto named = [&](const char* alias) -> const device::Parameter* {
        const auto found = profile.aliases.find(alias);
        return found == profile.aliases.end() ? nullptr : profile.find(found->second);
    };
    const device::Parameter* mode = named("MODE");
    if (mode && (mode->type != device::ValueType::enumeration || mode->enum_labels.empty())) mode = nullptr;
    return {named("PV"), named("SP"), mode, named("OUT")};
}

namespace {

bool is_number(const device::Parameter& parameter) {
    return parameter.type == device::ValueType::int16 || parameter.type == device::ValueType::uint16;
}

std::string device_topic_of(const MqttConfig& config, const std::string& device_name) {
    return fmt::format("{}/{}", config.prefix, device_name);
}

std::string device_id_of(const MqttConfig& config, const std::string& device_name) {
    return sanitized_level(fmt::format("{}_{}", config.gateway_name, device_name));
}

// What every entity of the device shares: its device block and its availability. The
// controller is reached through the gateway (via_device, the gateway's own device), and its
// page is the gateway's dashboard where the HTTP front serves one.
nlohmann::json entity_base(const MqttConfig& config, const std::string& device_name, const device::Profile& profile,
                           const std::string& object_id) {
    const std::string device_topic = device_topic_of(config, device_name);
    const std::string device_id = device_id_of(config, device_name);
    nlohmann::json device{{"identifiers", {device_id}}, {"name", device_name},
                          {"model", profile.model.empty() ? profile.title : profile.model},
                          {"via_device", gateway_device_id(config)}};
    if (!profile.manufacturer.empty()) device["manufacturer"] = profile.manufacturer;
    if (!config.configuration_url.empty()) device["configuration_url"] = config.configuration_url;
    return nlohmann::json{
        {"unique_id", object_id},
        {"device", std::move(device)},
        // Both the gateway's (its last will) and the device's (its polls, mapped to online or
        // offline on its availability topic; its status topic has the words): a value is only
        // current when the gateway is connected and the device answers.
        {"availability",
         {{{"topic", config.prefix + "/status"}, {"payload_available", "online"}, {"payload_not_available", "offline"}},
          {{"topic", device_topic + "/availability"}, {"payload_available", "online"}, {"payload_not_available", "offline"}}}},
        {"availability_mode", "all"},
    };
}

std::string climate_object_id(const MqttConfig& config, const std::string& device_name) {
    return sanitized_level(device_id_of(config, device_name) + "_control_loop");
}

// What a value topic holds when there is no value is a word: the device's status ("no-reply",
// "stale", "line-down", "wrong-device", "waiting", "error") or a special state ("under-range").
// Every template maps such a word to None, which Home Assistant takes for "unknown" (its
// payload_reset and PAYLOAD_NONE), never to text a number, a select or a thermostat rejects; the
// device's availability topic says besides whether it answers.
constexpr const char* numbers_only = "{{ value if value | is_number else None }}";

// Only the given words, else None: a select's options, an enum sensor's, a binary sensor's
// payloads (as JSON strings, which Jinja reads alike).
std::string words_only(const std::vector<std::string>& words) {
    return fmt::format("{{{{ value if value in {} else None }}}}", nlohmann::json(words).dump());
}

// A mode label meaning the loop does not control (Home Assistant's `off`).
bool means_off(const std::string& label) { return label == "standby" || label == "off" || label == "stop"; }

// The loop's mode on the thermostat: every device mode a preset (set on MODE's /set topic as
// it is), and Home Assistant's heat/off: off while the device is in its off-like mode, heat in
// any other; commanding off sends that mode, heat the first of the others (TC10: auto). Without
// an off-like mode, the loop always heats and only the presets change it.
void add_modes(nlohmann::json& doc, const MqttConfig& config, const std::string& device_topic, const device::Parameter& mode) {
    const std::string topic = fmt::format("{}/{}", device_topic, mode.name);
    const bool commanded = config.writes && mode.writable;
    std::vector<std::string> labels;
    std::string off;
    std::string heat;
    for (const auto& [code, label] : mode.enum_labels) {
        labels.push_back(label);
        if (means_off(label) && off.empty()) off = label;
        if (!means_off(label) && heat.empty()) heat = label;
    }
    doc["preset_modes"] = labels;
    doc["preset_mode_state_topic"] = topic;
    doc["preset_mode_value_template"] = words_only(labels);
    if (commanded) doc["preset_mode_command_topic"] = topic + "/set";
    doc["mode_state_topic"] = topic;
    if (off.empty() || heat.empty()) {
        doc["mode_state_template"] = fmt::format("{{{{ 'heat' if value in {} else None }}}}", nlohmann::json(labels).dump());
        return;
    }
    doc["modes"] = {"heat", "off"};
    doc["mode_state_template"] = fmt::format("{{{{ ('off' if value == {} else 'heat') if value in {} else None }}}}",
                                             nlohmann::json(off).dump(), nlohmann::json(labels).dump());
    if (!commanded) return;
    doc["mode_command_topic"] = topic + "/set";
    doc["mode_command_template"] =
        fmt::format("{{{{ {} if value == 'off' else {} }}}}", nlohmann::json(off).dump(), nlohmann::json(heat).dump());
}

}  // namespace

// The gateway's name alone: a controller's device is GATEWAY_DEVICE, never the name alone, so
// no configured device name can make one the other.
std::string gateway_device_id(const MqttConfig& config) { return sanitized_level(config.gateway_name); }

DiscoveryDocument gateway_document(const MqttConfig& config) {
    // GATEWAY_status: every controller's entity id has a device and a parameter level after the
    // gateway's name, and "status" holds no '_' to split into two.
    const std::string object_id = sanitized_level(config.gateway_name + "_status");
    nlohmann::json device{{"identifiers", {gateway_device_id(config)}}, {"name", config.gateway_name}, {"model", "loopwire gateway"},
                          {"manufacturer", "loopwire"}, {"sw_version", std::string(loopwire::version())}};
    if (!config.configuration_url.empty()) device["configuration_url"] = config.configuration_url;
    // The gateway's status topic is its connection: "online", and "offline" from its last will
    // or a clean stop. No availability of its own: offline is the state to show, not unknown.
    nlohmann::json doc{{"unique_id", object_id},
                       {"name", "connected"},
                       {"device", std::move(device)},
                       {"state_topic", config.prefix + "/status"},
                       {"payload_on", "online"},
                       {"payload_off", "offline"},
                       {"device_class", "connectivity"},
                       {"entity_category", "diagnostic"}};
    return {fmt::format("{}/binary_sensor/{}/config", config.discovery_prefix, object_id), std::move(doc)};
}

std::optional<DiscoveryDocument> climate_document(const MqttConfig& config, const std::string& device_name,
                                                  const device::Profile& profile, const ControlLoopSample& sample) {
    const ControlLoop loop = control_loop_of(profile);
    if (!loop.pv || !loop.sp || !is_number(*loop.pv) || !is_number(*loop.sp)) return std::nullopt;
    // Home Assistant's climate takes temperatures in C or F only.
    if (sample.pv_unit != "°C" && sample.pv_unit != "°F") return std::nullopt;
    const std::string device_topic = device_topic_of(config, device_name);
    const std::string object_id = climate_object_id(config, device_name);
    nlohmann::json doc = entity_base(config, device_name, profile, object_id);
    doc["name"] = "control loop";
    doc["current_temperature_topic"] = fmt::format("{}/{}", device_topic, loop.pv->name);
    doc["current_temperature_template"] = numbers_only;
    doc["temperature_state_topic"] = fmt::format("{}/{}", device_topic, loop.sp->name);
    doc["temperature_state_template"] = numbers_only;
    if (config.writes && loop.sp->writable) doc["temperature_command_topic"] = fmt::format("{}/{}/set", device_topic, loop.sp->name);
    // The unit the device is set to, as its PV's unit word says (°C or °F): Home Assistant
    // converts to the user's unit itself, and would otherwise take the device's numbers for its own.
    doc["temperature_unit"] = sample.pv_unit == "°C" ? "C" : "F";
    // The slider spans the set point's limits as the device holds them (or its profile's fixed
    // ones); none known: Home Assistant's defaults, not what the word can hold.
    put_limits(doc, sample.sp_limits, "min_temp", "max_temp");
    doc["temp_step"] = std::pow(10.0, -sample.sp_decimals);
    // Home Assistant shows temperatures to 0.1, 0.5 or 1.
    doc["precision"] = sample.sp_decimals > 0 ? 0.1 : 1.0;
    doc["modes"] = {"heat"};
    if (loop.mode && sample.mode_polled) {
        add_modes(doc, config, device_topic, *loop.mode);
    } else {
        // Without a mode word the loop always controls: heat while its set point reads, unknown
        // while the device does not answer (Home Assistant would otherwise take it for off).
        doc["mode_state_topic"] = doc["temperature_state_topic"];
        doc["mode_state_template"] = "{{ 'heat' if value | is_number else None }}";
    }
    // What the loop does now, from its control output (alias OUT, in %) where it is polled:
    // heating while it drives the output, cooling below 0 (a heat/cool loop's second output),
    // idle at 0.
    if (loop.out && is_number(*loop.out) && sample.out_polled) {
        doc["action_topic"] = fmt::format("{}/{}", device_topic, loop.out->name);
        doc["action_template"] =
            "{{ ('heating' if value | float > 0 else 'cooling' if value | float < 0 else 'idle') if value | is_number else None }}";
    }
    return DiscoveryDocument{climate_topic(config, device_name), std::move(doc)};
}

std::string climate_topic(const MqttConfig& config, const std::string& device_name) {
    return fmt::format("{}/climate/{}/config", config.discovery_prefix, climate_object_id(config, device_name));
}

DiscoveryDocument discovery_document(const MqttConfig& config, const std::string& device_name, const device::Profile& profile,
                                     const device::Parameter& parameter, const ValueChange* latest) {
    const std::string device_topic = device_topic_of(config, device_name);
    const std::string state_topic = fmt::format("{}/{}", device_topic, parameter.name);
    const std::string object_id = sanitized_level(fmt::format("{}_{}", device_id_of(config, device_name), parameter.name));
    const bool commands = config.writes && parameter.writable;

    nlohmann::json doc = entity_base(config, device_name, profile, object_id);
    doc["name"] = friendly_name(parameter);
    doc["state_topic"] = state_topic;
    // The latest value's unit is device::shown_unit's (value_cache.cpp); "?" is no unit to show.
    std::string unit = latest ? latest->unit : parameter.unit;
    if (unit == device::unknown_unit) unit.clear();
    if (!unit.empty()) doc["unit_of_measurement"] = unit;
    if (const auto device_class = device_class_of(unit); !device_class.empty()) doc["device_class"] = device_class;

    std::string component;
    std::string on;
    std::string off;
    const bool numeric = is_number(parameter);
    if (numeric && commands) {
        component = "number";
        const int decimals = shown_decimals(parameter, latest);
        doc["command_topic"] = state_topic + "/set";
        // Before a value: the limits nothing read is needed for (a fixed bound in engineering units).
        const device::ValueLimits known = latest ? latest->limits : device::limits_of(parameter, {});
        put_limits(doc, known, "min", "max");
        doc["step"] = std::pow(10.0, -decimals);
        doc["value_template"] = numbers_only;
        doc["mode"] = "box";
    } else if (commands && (parameter.type == device::ValueType::enumeration || parameter.type == device::ValueType::boolean)) {
        component = "select";
        doc["command_topic"] = state_topic + "/set";
        const std::vector<std::string> options =
            parameter.type == device::ValueType::boolean && two_state_labels(parameter, on, off) ? std::vector{off, on}
                                                                                                 : labels_of(parameter);
        doc["options"] = options;
        doc["value_template"] = words_only(options);
        doc.erase("unit_of_measurement");
        doc.erase("device_class");
    } else if (two_state_labels(parameter, on, off)) {
        component = "binary_sensor";
        doc["payload_on"] = on;
        doc["payload_off"] = off;
        doc["value_template"] = words_only({on, off});
        doc.erase("unit_of_measurement");
        doc.erase("device_class");
    } else {
        component = "sensor";
        if (numeric) {
            doc["value_template"] = numbers_only;
            doc["state_class"] = "measurement";
            doc["suggested_display_precision"] = shown_decimals(parameter, latest);
        } else if (parameter.type == device::ValueType::enumeration && !parameter.enum_labels.empty()) {
            doc["device_class"] = "enum";
            doc["options"] = labels_of(parameter);
            doc["value_template"] = words_only(labels_of(parameter));
            doc.erase("unit_of_measurement");
        }
    }
    if (const auto category = entity_category_of(profile, parameter, component == "number" || component == "select")) {
        doc["entity_category"] = *category;
    }
    return {fmt::format("{}/{}/{}/config", config.discovery_prefix, component, object_id), std::move(doc)};
}

std::vector<DiscoveryDocument> bit_documents(const MqttConfig& config, const std::string& device_name,
                                             const device::Profile& profile, const device::Parameter& parameter) {
    std::vector<DiscoveryDocument> documents;
    if (parameter.type != device::ValueType::bitfield) return documents;
    const std::string state_topic = fmt::format("{}/{}", device_topic_of(config, device_name), parameter.name);
    for (const auto& [bit, name] : parameter.bit_names) {
        const std::string object_id = sanitized_level(fmt::format("{}_{}_{}", device_id_of(config, device_name), parameter.name, name));
        nlohmann::json doc = entity_base(config, device_name, profile, object_id);
        doc["name"] = fmt::format("{}: {}", friendly_name(parameter), name);
        doc["state_topic"] = state_topic;
        // The state is the field's text, the set bits' names: "{alarm_1, loop_break_alarm}"
        // (device::value_text); the name is quoted as a JSON string, which Jinja reads alike.
        // A status word in its place ("no-reply") is no set of bits: unknown.
        doc["value_template"] = fmt::format("{{{{ ('ON' if {} in value[1:-1].split(', ') else 'OFF') if value[:1] == '{{' else None }}}}",
                                            nlohmann::json(name).dump());
        if (names_a_problem(name)) doc["device_class"] = "problem";
        if (parameter.persistent) doc["entity_category"] = "diagnostic";
        documents.push_back({fmt::format("{}/binary_sensor/{}/config", config.discovery_prefix, object_id), std::move(doc)});
    }
    return documents;
}

}  // namespace loopwire::gateway
