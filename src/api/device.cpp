#include <loopwire/device.hpp>

#include <fmt/format.h>

#include "api/device_spec.hpp"
#include "api/failure_translation.hpp"
#include "api/link_state.hpp"
#include "client/device_client.hpp"
#include "client/resolved_value.hpp"
#include "profile/request_planner.hpp"
#include "profile/value_format.hpp"

namespace loopwire {

struct Device::State {
    std::shared_ptr<Link::State> link;  // kept open while the device is used
    device::DeviceClient client;
};

namespace {

// The library's reading is the resolved view every front shows (client/resolved_value.hpp).
Reading to_reading(const device::ParameterReading& reading, const device::RawValues& known) {
    const device::Parameter& parameter = *reading.parameter;
    const device::ResolvedValue resolved = device::resolve_reading(reading, known);
    Reading result;
    result.name = parameter.name;
    result.mnemonic = parameter.mnemonic;
    result.number = resolved.number;
    result.text = resolved.text;
    result.unit = resolved.unit;
    result.min = resolved.limits.min;
    result.max = resolved.limits.max;
    result.status = resolved.status;
    result.error = resolved.error;
    result.raw = resolved.raw.value_or(0);
    if (!resolved.raw) result.state = ValueStatus::error;
    else if (resolved.status == "ok") result.state = ValueStatus::ok;
    else if (resolved.status == device::unknown_label_status) result.state = ValueStatus::unlisted_code;
    else result.state = ValueStatus::special_state;
    return result;
}

const device::Parameter& single_parameter(const device::Profile& profile, const std::string& name) {
    auto found = api::value_or_throw(device::resolve_parameters(profile, {name}));
    if (found.size() != 1) {
        throw Failure(Failure::Kind::usage, fmt::format("'{}' names a group of {} parameters: read it with read({{names}}), "
                                                        "write its parameters one by one",
                                                        name, found.size()));
    }
    return *found.front();
}

}  // namespace

Device::Device(Link link, const std::string& device_name) {
    auto address = api::value_or_throw(api::resolve_device(device_name));
    state_ = std::make_shared<State>(State{link.state_, device::DeviceClient(*link.state_->master, std::move(address))});
}

std::string Device::profile_id() const { return state_->client.device().profile->id; }

int Device::unit() const { return state_->client.device().unit; }

std::vector<Reading> Device::read(const std::vector<std::string>& names) {
    const auto parameters = api::value_or_throw(device::resolve_parameters(*state_->client.device().profile, names));
    const device::ReadReport report = state_->client.read_with_limits(parameters);
    std::vector<Reading> readings;
    readings.reserve(report.readings.size());
    for (const auto& reading : report.readings) readings.push_back(to_reading(reading, report.raw));
    return readings;
}

Reading Device::read(const std::string& name) {
    const device::Parameter& parameter = single_parameter(*state_->client.device().profile, name);
    const device::ReadReport report = state_->client.read_with_limits({&parameter});
    if (report.first_error) api::throw_failure(*report.first_error);
    return to_reading(report.readings.front(), report.raw);
}

void Device::write(const std::string& name, const std::string& value) { write({{name, value}}); }

void Device::write(const std::vector<std::pair<std::string, std::string>>& assignments) {
    const device::Profile& profile = *state_->client.device().profile;
    std::vector<std::pair<const device::Parameter*, std::string>> resolved;
    resolved.reserve(assignments.size());
    for (const auto& [name, value] : assignments) {
        const device::Parameter& parameter = single_parameter(profile, name);
        // Refused before anything is read or sent, as the command line does.
        if (!parameter.writable) {
            throw Failure(Failure::Kind::usage, fmt::format("{} ({}) is read-only", parameter.name, parameter.mnemonic));
        }
        resolved.emplace_back(&parameter, value);
    }
    auto written = state_->client.write(resolved);
    if (!written) api::throw_failure(written.error());
}

}  // namespace loopwire
