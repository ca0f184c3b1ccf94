#include "gateway/config_change.hpp"

#include <map>
#include <vector>

#include <fmt/format.h>

namespace loopwire::gateway {
namespace {

template <typename Named>
std::map<std::string, const Named*> by_name(const std::vector<Named>& items) {
    std::map<std::string, const Named*> named;
    for (const Named& item : items) named.emplace(item.name, &item);
    return named;
}

std::string devices_counted(std::size_t n) { return n == 1 ? "1 device" : fmt::format("{} devices", n); }

// A line both configurations have: its devices added, removed or changed, and the line itself
// changed when anything but its devices is (the link, timeouts, retries).
void compare_line(const LineConfig& before, const LineConfig& after, std::vector<std::string>& changes) {
    const auto old_devices = by_name(before.devices);
    const auto new_devices = by_name(after.devices);
    for (const auto& [name, device] : old_devices) {
        if (new_devices.count(name) == 0) {
            changes.push_back(fmt::format("device {} removed from line {}", name, after.name));
        }
    }
    for (const auto& [name, device] : new_devices) {
        const auto old = old_devices.find(name);
        if (old == old_devices.end()) {
            changes.push_back(fmt::format("device {} added to line {}", name, after.name));
        } else if (!(*old->second == *device)) {
            changes.push_back(fmt::format("device {} changed", name));
        }
    }
    LineConfig same_devices = after;
    same_devices.devices = before.devices;
    if (!(same_devices == before)) changes.push_back(fmt::format("line {} changed", after.name));
}

template <typename Table>
void compare_table(const char* name, const std::optional<Table>& before, const std::optional<Table>& after,
                   std::vector<std::string>& changes) {
    if (before && !after) changes.push_back(fmt::format("[{}] removed", name));
    if (!before && after) changes.push_back(fmt::format("[{}] added", name));
    if (before && after && !(*before == *after)) changes.push_back(fmt::format("[{}] changed", name));
}

}  // namespace

std::string describe_config_change(const GatewayConfig& before, const GatewayConfig& after) {
    std::vector<std::string> changes;
    const auto old_lines = by_name(before.lines);
    const auto new_lines = by_name(after.lines);
    for (const auto& [name, line] : old_lines) {
        if (new_lines.count(name) == 0) {
            changes.push_back(fmt::format("line {} removed ({})", name, devices_counted(line->devices.size())));
        }
    }
    for (const auto& [name, line] : new_lines) {
        const auto old = old_lines.find(name);
        if (old == old_lines.end()) {
            changes.push_back(fmt::format("line {} added ({})", name, devices_counted(line->devices.size())));
        } else {
            compare_line(*old->second, *line, changes);
        }
    }
    if (before.name != after.name) {
        changes.push_back(fmt::format("[gateway] name \"{}\" → \"{}\"", before.name, after.name));
    }
    // [modbus_tcp] is always there (enabled = false turns it off).
    if (before.modbus_tcp.enabled != after.modbus_tcp.enabled) {
        changes.push_back(after.modbus_tcp.enabled ? "[modbus_tcp] enabled" : "[modbus_tcp] disabled");
    } else if (!(before.modbus_tcp == after.modbus_tcp)) {
        changes.push_back("[modbus_tcp] changed");
    }
    compare_table("mqtt", before.mqtt, after.mqtt, changes);
    compare_table("sparkplug", before.sparkplug, after.sparkplug, changes);
    compare_table("http", before.http, after.http, changes);
    compare_table("history", before.history, after.history, changes);
    if (!(before.log == after.log)) changes.push_back("[log] changed");
    if (changes.empty()) return "nothing changed";
    std::string text;
    for (const std::string& change : changes) text += (text.empty() ? "" : "; ") + change;
    return text;
}

AuditRecord reload_record(const std::string& who, const std::string& file, std::string change, std::string outcome) {
    AuditRecord record;
    record.origin = {"reload", who, ""};
    record.device = "";
    record.parameter = fmt::format("configuration {}", file);
    record.new_value = std::move(change);
    // A configuration's mistakes come one a line: the audit's row keeps to one (CSV, the log).
    for (std::size_t at = outcome.find('\n'); at != std::string::npos; at = outcome.find('\n', at)) {
        outcome.replace(at, 1, "; ");
    }
    record.outcome = std::move(outcome);
    return record;
}

}  // namespace loopwire::gateway
