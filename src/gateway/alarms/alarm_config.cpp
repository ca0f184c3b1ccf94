#include "gateway/alarms/alarm_config.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include <fmt/format.h>

#include "common/peer_text.hpp"
#include "common/text_parsing.hpp"
#include "gateway/config_schema.hpp"
#include "gateway/gateway_config.hpp"
#include "profile/request_planner.hpp"

namespace loopwire::gateway::alarms {
namespace {

struct Where {
    const std::string& source;
    std::vector<Error>& mistakes;
    std::string path;  // "alarms.limits[0]"

    void fail(const toml::source_region& region, std::string_view key, const std::string& what) const {
        const auto line = std::max<toml::source_index>(region.begin.line, 1);
        const std::string at = key.empty() ? path : fmt::format("{}.{}", path, key);
        mistakes.push_back(make_error(ErrorKind::usage, fmt::format("{}:{}: {}: {}", source, line, at, without_control_bytes(what))));
    }
};

const toml::source_region& region_of(const toml::table& table, std::string_view key) {
    const toml::node* node = table.get(key);
    return node ? node->source() : table.source();
}

std::optional<std::string> text_of(const Where& where, const toml::table& table, std::string_view key, bool required,
                                   std::string_view example) {
    const toml::node* node = table.get(key);
    if (!node) {
        if (required) where.fail(table.source(), "", fmt::format("missing `{}` (e.g. {} = {})", key, key, example));
        return std::nullopt;
    }
    if (const auto* text = node->as_string()) return text->get();
    where.fail(node->source(), key, fmt::format("expected a string such as {}", example));
    return std::nullopt;
}

std::optional<double> number_of(const Where& where, const toml::table& table, std::string_view key) {
    const toml::node* node = table.get(key);
    if (!node) return std::nullopt;
    if (const auto* number = node->as_floating_point()) return number->get();
    if (const auto* integer = node->as_integer()) return static_cast<double>(integer->get());
    where.fail(node->source(), key, "expected a number such as 250 or 12.5");
    return std::nullopt;
}

std::chrono::milliseconds delay_of(const Where& where, const toml::table& table, std::string_view key) {
    auto text = text_of(where, table, key, false, "\"10s\"");
    if (!text) return {};
    auto parsed = parse_duration(*text, "");
    if (!parsed) {
        const std::string& message = parsed.error().message;
        where.fail(region_of(table, key), key, message.substr(std::min(message.find_first_not_of(' '), message.size())));
        return {};
    }
    const ConfigRange& range = config_range("alarms.limits", key);
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(*parsed);
    if (static_cast<double>(ms.count()) < range.least || static_cast<double>(ms.count()) > range.most) {
        where.fail(region_of(table, key), key,
                   fmt::format("{} is out of range (expected {}); leave the key out for no delay", quoted_excerpt(*text),
                               config_key("alarms.limits", key).bounds));
        return {};
    }
    return ms;
}

bool valid_name(std::string_view name) {
    return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '-' || c == '_';
    });
}

const DeviceConfig* device_named(const std::vector<LineConfig>& lines, std::string_view name) {
    for (const LineConfig& line : lines) {
        for (const DeviceConfig& device : line.devices) {
            if (device.name == name) return &device;
        }
    }
    return nullptr;
}

// The parameter's name in the profile when it is a polled number of the device; else its mistake is noted.
std::optional<std::string> numeric_parameter(const Where& where, const toml::table& table, std::string_view key,
                                             const DeviceConfig& device, const std::string& name) {
    auto resolved = device::resolve_parameters(*device.address.profile, {name});
    if (!resolved || resolved->size() != 1) {
        where.fail(region_of(table, key), key, fmt::format("device \"{}\" ({}) has no parameter \"{}\"", device.name,
                                                           device.address.profile->id, name));
        return std::nullopt;
    }
    const device::Parameter& parameter = *resolved->front();
    const bool number = (parameter.type == device::ValueType::int16 || parameter.type == device::ValueType::uint16) &&
                        parameter.enum_labels.empty() && parameter.bit_names.empty();
    if (!number) {
        where.fail(region_of(table, key), key, fmt::format("\"{}\" is not a number (an enumeration, bit field or switch): "
                                                           "a limit alarm compares numbers", parameter.name));
        return std::nullopt;
    }
    const auto polled = polled_parameters(device);
    if (std::find(polled.begin(), polled.end(), &parameter) == polled.end()) {
        where.fail(region_of(table, key), key, fmt::format("\"{}\" is not polled: add it to device \"{}\"'s parameters",
                                                           parameter.name, device.name));
        return std::nullopt;
    }
    return parameter.name;
}

std::optional<LimitAlarm> parse_limit(const Where& where, const toml::table& table, const std::vector<LineConfig>& lines) {
    const std::vector<std::string_view> allowed = config_keys_of("alarms.limits");
    bool fine = true;
    for (auto&& [key, node] : table) {
        if (std::find(allowed.begin(), allowed.end(), key.str()) != allowed.end()) continue;
        where.fail(key.source(), key.str(), fmt::format("unknown key (allowed here: {})", fmt::join(allowed, ", ")));
        fine = false;
    }
    LimitAlarm alarm;
    const auto device_name = text_of(where, table, "device", true, "\"oven\"");
    const auto parameter = text_of(where, table, "parameter", true, "\"measured_value\"");
    const auto kind = text_of(where, table, "kind", true, "\"high\"");
    const auto setpoint = text_of(where, table, "setpoint", false, "\"set_point\"");
    const auto limit = number_of(where, table, "limit");
    if (!table.get("limit")) where.fail(table.source(), "", "missing `limit` (e.g. limit = 250)");
    const DeviceConfig* device = device_name ? device_named(lines, *device_name) : nullptr;
    if (device_name && !device) {
        where.fail(region_of(table, "device"), "device", fmt::format("no device \"{}\" in [[lines.devices]]", *device_name));
    }
    if (kind) {
        if (auto known = limit_kind_named(*kind)) {
            alarm.kind = *known;
        } else {
            where.fail(region_of(table, "kind"), "kind",
                       fmt::format("{} is not a kind: high, high_high, low, low_low or deviation", quoted_excerpt(*kind)));
            fine = false;
        }
    }
    if (kind && alarm.kind == LimitKind::deviation && !setpoint) {
        where.fail(table.source(), "", "a deviation alarm needs `setpoint`, the parameter PV is compared with (e.g. setpoint = \"set_point\")");
        fine = false;
    }
    // A setpoint left on an alarm whose kind was changed from deviation is not read (the schema says so).
    if (device && parameter) {
        if (auto name = numeric_parameter(where, table, "parameter", *device, *parameter)) alarm.parameter = *name; else fine = false;
    }
    if (device && setpoint && alarm.kind == LimitKind::deviation) {
        if (auto name = numeric_parameter(where, table, "setpoint", *device, *setpoint)) alarm.setpoint = *name; else fine = false;
    }
    if (limit) {
        if (!std::isfinite(*limit) || (alarm.kind == LimitKind::deviation && *limit < 0)) {
            where.fail(region_of(table, "limit"), "limit", "a deviation's limit is the largest |PV - SP| allowed: 0 or more");
            fine = false;
        }
        alarm.limit = *limit;
    }
    if (auto deadband = number_of(where, table, "deadband")) {
        if (!(*deadband >= 0) || !std::isfinite(*deadband)) {
            where.fail(region_of(table, "deadband"), "deadband", "expected 0 or more, in the parameter's unit");
            fine = false;
        }
        alarm.deadband = *deadband;
    }
    alarm.on_delay = delay_of(where, table, "on_delay");
    alarm.off_delay = delay_of(where, table, "off_delay");
    if (auto severity = text_of(where, table, "severity", false, "\"high\"")) {
        if (auto known = severity_named(*severity)) {
            alarm.severity = *known;
        } else {
            where.fail(region_of(table, "severity"), "severity",
                       fmt::format("{} is not a severity: low, medium, high or critical", quoted_excerpt(*severity)));
            fine = false;
        }
    }
    if (auto message = text_of(where, table, "message", false, "\"oven too hot\"")) alarm.message = *message;
    if (auto name = text_of(where, table, "name", false, "\"too_hot\"")) {
        if (!valid_name(*name)) {
            where.fail(region_of(table, "name"), "name", "letters, digits, '-' and '_' only");
            fine = false;
        }
        alarm.name = *name;
    } else {
        alarm.name = fmt::format("{}_{}", alarm.parameter, name_of(alarm.kind));
    }
    if (!fine || !device || alarm.parameter.empty() || !limit) return std::nullopt;
    alarm.device = device->name;
    return alarm;
}

}  // namespace

std::vector<LimitAlarm> parse_alarm_limits(const toml::table& root, const std::string& source,
                                           const std::vector<LineConfig>& lines, std::vector<Error>& mistakes) {
    std::vector<LimitAlarm> limits;
    const toml::node* alarms_node = root.get("alarms");
    if (!alarms_node) return limits;
    Where top{source, mistakes, "alarms"};
    const toml::table* alarms_table = alarms_node->as_table();
    if (!alarms_table) {
        top.fail(alarms_node->source(), "", "expected a table: [[alarms.limits]]");
        return limits;
    }
    const std::vector<std::string_view> allowed = config_keys_of("alarms");
    for (auto&& [key, node] : *alarms_table) {
        if (std::find(allowed.begin(), allowed.end(), key.str()) == allowed.end()) {
            top.fail(key.source(), key.str(), fmt::format("unknown key (allowed here: {})", fmt::join(allowed, ", ")));
        }
    }
    const toml::node* list_node = alarms_table->get("limits");
    if (!list_node) return limits;
    const toml::array* list = list_node->as_array();
    if (!list || !list->is_array_of_tables()) {
        top.fail(list_node->source(), "limits", "expected [[alarms.limits]] tables");
        return limits;
    }
    std::set<std::string> ids;
    for (std::size_t i = 0; i < list->size(); ++i) {
        const toml::table& table = *list->get(i)->as_table();
        Where where{source, mistakes, fmt::format("alarms.limits[{}]", i)};
        auto alarm = parse_limit(where, table, lines);
        if (!alarm) continue;
        if (!ids.insert(alarm_id(alarm->device, alarm->name)).second) {
            where.fail(table.source(), "name", fmt::format("device \"{}\" has two alarms named \"{}\": give one another `name`",
                                                           alarm->device, alarm->name));
            continue;
        }
        limits.push_back(std::move(*alarm));
    }
    return limits;
}

}  // namespace loopwire::gateway::alarms
