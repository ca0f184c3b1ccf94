#include "devices/simulated_units.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "client/device_client.hpp"
#include "devices/registry.hpp"
#include "simulation/register_bank.hpp"

namespace loopwire::device::models {
namespace {

std::string parity_text(transport::Parity parity) {
    switch (parity) {
        case transport::Parity::none: return "none";
        case transport::Parity::even: return "even";
        case transport::Parity::odd: return "odd";
    }
    return "?";
}

bool listed(const std::vector<std::string>& list, const std::string& item) {
    return std::find(list.begin(), list.end(), item) != list.end();
}

// The simulator serves whatever link it is given (a test may want the "wrong" settings), but
// says so when the real device could not be set that way (profile protocols and
// serial_defaults.parities; e.g. the ramp/soak controller has no 'no parity', §1 Level 3).
std::vector<std::string> link_mismatches(const Profile& profile, std::uint8_t unit, const transport::LinkUrl& link) {
    std::vector<std::string> warnings;
    if (!link.is_serial()) return warnings;
    const std::string framing = transport::framing_name(link.framing);
    if (!listed(profile.protocols, framing)) {
        warnings.push_back(fmt::format("unit {} ({}): the real device does not speak {} (it speaks {})", unit, profile.id,
                                       framing, fmt::join(profile.protocols, ", ")));
    }
    const std::string parity = parity_text(link.serial.parity);
    if (!listed(profile.parities, parity)) {
        warnings.push_back(fmt::format("unit {} ({}): the real device cannot be set to parity {} (it offers {}); add "
                                       "?parity={} to the link to match it",
                                       unit, profile.id, parity, fmt::join(profile.parities, ", "), profile.default_parity));
    }
    return warnings;
}

Result<void> claim(SimulatedUnits& result, int unit) {
    if (result.units.contains(static_cast<std::uint8_t>(unit))) {
        return make_error(ErrorKind::usage, fmt::format("unit {} is given twice; each unit id can be served once", unit));
    }
    return {};
}

}  // namespace

Result<SimulatedUnits> build_simulated_units(const ProfileRegistry& profiles, const std::vector<int>& bank_units, const std::vector<std::string>& devices,
                                             const transport::LinkUrl& link,
                                             const SimulationEnvironment& environment) {
    SimulatedUnits result;
    for (const std::string& text : devices) {
        auto device = parse_device_address(profiles, text);
        if (!device) return device.error();
        if (auto free = claim(result, device->unit); !free) return free.error();
        auto simulated = models::make_simulated_device(
            device->profile, environment.on_line(device->unit, link));
        result.units[device->unit] = simulated;
        result.devices[device->unit] = simulated;
        result.descriptions.push_back(fmt::format("{}: {} ({})", device->unit, device->profile->id, device->profile->title));
        auto warnings = link_mismatches(*device->profile, device->unit, link);
        result.warnings.insert(result.warnings.end(), warnings.begin(), warnings.end());
    }
    std::vector<int> banks = bank_units;
    if (banks.empty() && devices.empty()) banks.push_back(1);
    for (int unit : banks) {
        if (auto free = claim(result, unit); !free) return free.error();
        result.units[static_cast<std::uint8_t>(unit)] = std::make_shared<session::RegisterBank>();
        result.descriptions.push_back(fmt::format("{}: plain register bank", unit));
    }
    return result;
}

Result<void> apply_fault_option(SimulatedUnits& units, const std::string& option) {
    const auto colon = option.rfind(':');
    if (colon == std::string::npos) {
        return make_error(ErrorKind::usage, fmt::format("--fault '{}': write DEVICE@UNIT:FAULT, e.g. tc10@3:open-input", option));
    }
    // Compared with the simulated units only, so the id needs no profile lookup here.
    auto address = split_device_address(option.substr(0, colon));
    if (!address) return address.error();
    const auto found = units.devices.find(address->unit);
    if (found == units.devices.end() || found->second->profile().id != address->id) {
        return make_error(ErrorKind::usage, fmt::format("--fault '{}': unit {} is not simulated as {}; add --device {}@{}",
                                                        option, address->unit, address->id, address->id, address->unit));
    }
    if (auto applied = found->second->inject_fault(option.substr(colon + 1)); !applied) {
        return make_error(ErrorKind::usage, fmt::format("--fault '{}': {}", option, applied.error().message));
    }
    return {};
}

}  // namespace loopwire::device::models
