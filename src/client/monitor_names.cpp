#include "client/monitor_names.hpp"

#include <algorithm>
#include <map>
#include <optional>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

// Per built-in profile: process value, set point (the one a user writes, and the one in force
// where they differ), output, alarm/status word and control mode, so that every front shows
// the loop and what a write changed (PV, SP and OUT are the profiles' aliases).
// TC10 (manual §5.1, words 1A, 3A, 4A, 10A, 15A; §5.3.8 #79, word 717): measured value rV, the set
// point SP, the operating set point, output power, alarm status word, control state
// (auto/manual/standby). Ramp/soak (§7 Register Map, rows 008AH, 0000H, 0087H, 0088H): PV, SV
// (its only set point), OUT%, controller information bits. AC20 ("Words for device in control
// mode", words 123, 125, 138, 137, 130, 135): the carbon potential it controls,
// the probe temperature, the main set point SP, the operative set point, the main control output
// and the device status (which carries its mode).
const std::map<std::string, std::vector<std::string>>& builtin_defaults() {
    static const std::map<std::string, std::vector<std::string>> defaults{
        {"tc10", {"measured_value", "set_point", "operating_set_point", "output_power", "alarm_status", "control_state"}},
        {"rampsoak", {"process_value", "set_value", "output_percentage", "controller_status"}},
        {"ac20", {"carbon_potential", "probe_temperature", "main_set_point", "operative_set_point", "main_output_value",
                  "device_status"}},
    };
    return defaults;
}

std::string label_of(const device::DeviceAddress& device) { return fmt::format("{}@{}", device.profile->id, device.unit); }

bool same_device(const device::DeviceAddress& a, const device::DeviceName& b) {
    return a.profile->id == b.id && a.unit == b.unit;
}

void append_new(std::vector<const device::Parameter*>& list, const std::vector<const device::Parameter*>& more) {
    for (const auto* p : more) {
        if (std::find(list.begin(), list.end(), p) == list.end()) list.push_back(p);
    }
}

// "tc10@3:SP" -> ("tc10@3", "SP"); a plain name -> ("", name). Only a ':' after an '@' splits,
// so names and mnemonics are never cut.
std::pair<std::string, std::string> split_target(const std::string& text) {
    const auto at = text.find('@');
    const auto colon = at == std::string::npos ? std::string::npos : text.find(':', at);
    if (colon == std::string::npos) return {"", text};
    return {text.substr(0, colon), text.substr(colon + 1)};
}

Result<void> apply_to_one(const std::vector<device::DeviceAddress>& devices, const std::string& target, const std::string& name,
                          std::vector<std::vector<const device::Parameter*>>& lists) {
    // Only compared with the --device options, so the id needs no profile lookup here.
    auto address = device::split_device_address(target);
    if (!address) return address.error();
    for (std::size_t i = 0; i < devices.size(); ++i) {
        if (!same_device(devices[i], *address)) continue;
        auto found = device::resolve_parameters(*devices[i].profile, {name});
        if (!found) return found.error();
        append_new(lists[i], *found);
        return {};
    }
    return make_error(ErrorKind::usage, fmt::format("'{}:{}' names {}, which is not one of the --device options", target, name, target));
}

// A plain NAME must name something on every device: one it matches nothing on is an error (a
// typo there would otherwise leave that device on its defaults without a word). The error
// names the device, suggests the nearest names there, and where the NAME does match on others,
// how to name it for those alone.
Result<void> apply_to_all(const std::vector<device::DeviceAddress>& devices, const std::string& name,
                          std::vector<std::vector<const device::Parameter*>>& lists) {
    std::vector<std::vector<const device::Parameter*>> found_per_device;
    std::vector<std::string> matched_on;
    std::optional<std::pair<std::size_t, Error>> first_miss;
    for (std::size_t i = 0; i < devices.size(); ++i) {
        auto found = device::resolve_parameters(*devices[i].profile, {name});
        if (!found) {
            if (!first_miss) first_miss.emplace(i, found.error());
            found_per_device.emplace_back();
            continue;
        }
        found_per_device.push_back(std::move(*found));
        matched_on.push_back(label_of(devices[i]));
    }
    if (first_miss) {
        const auto& [index, error] = *first_miss;
        if (devices.size() == 1) return error;
        std::string message = fmt::format("{}: {}", label_of(devices[index]), error.message);
        if (!matched_on.empty()) {
            message += fmt::format("; a NAME without DEVICE@UNIT: must match on every --device: write {}:{} to watch it on {} alone",
                                   matched_on.front(), name, matched_on.front());
        }
        return make_error(error.kind, message);
    }
    for (std::size_t i = 0; i < devices.size(); ++i) append_new(lists[i], found_per_device[i]);
    return {};
}

}  // namespace

std::vector<const device::Parameter*> default_watch_list(const device::Profile& profile) {
    std::vector<const device::Parameter*> list;
    if (auto known = builtin_defaults().find(profile.id); known != builtin_defaults().end()) {
        for (const auto& name : known->second) {
            if (const auto* p = profile.find(name)) list.push_back(p);
        }
        return list;
    }
    for (const auto& p : profile.parameters) {
        if (list.size() == 4) break;
        if (p.readable && !p.hidden) list.push_back(&p);
    }
    return list;
}

Result<std::vector<std::vector<const device::Parameter*>>> watch_lists(const std::vector<device::DeviceAddress>& devices,
                                                                       const std::vector<std::string>& names) {
    std::vector<std::vector<const device::Parameter*>> lists(devices.size());
    for (const auto& text : names) {
        const auto [target, name] = split_target(text);
        auto applied = target.empty() ? apply_to_all(devices, name, lists) : apply_to_one(devices, target, name, lists);
        if (!applied) return applied.error();
    }
    for (std::size_t i = 0; i < devices.size(); ++i) {
        // Write-only entries cannot be watched (the planner leaves them out): drop them here so
        // they do not show as forever unread.
        std::erase_if(lists[i], [](const device::Parameter* p) { return !p->readable; });
        if (lists[i].empty()) lists[i] = default_watch_list(*devices[i].profile);
    }
    return lists;
}

}  // namespace loopwire::device
