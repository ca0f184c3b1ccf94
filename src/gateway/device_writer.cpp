#include "gateway/device_writer.hpp"

#include <fmt/format.h>

#include "gateway/scheduled_master.hpp"
#include "profile/request_planner.hpp"

namespace loopwire::gateway {

struct DeviceWriter::Target {
    Target(WritableDevice writable, std::chrono::milliseconds write_limit)
        : device(std::move(writable)), master(device.line, "write " + device.name, Priority::write, write_limit) {}

    WritableDevice device;
    ScheduledMaster master;  // at Priority::write on the device's line; safe from several threads
};

DeviceWriter::DeviceWriter(std::vector<WritableDevice> devices, std::chrono::milliseconds write_limit) {
    for (auto& device : devices) targets_.push_back(std::make_unique<Target>(std::move(device), write_limit));
}

DeviceWriter::~DeviceWriter() = default;

const WritableDevice* DeviceWriter::find(const std::string& name) const {
    for (const auto& target : targets_) {
        if (target->device.name == name) return &target->device;
    }
    return nullptr;
}

Result<WrittenValues> DeviceWriter::write(const std::string& device, const std::vector<WriteAssignment>& assignments) const {
    Target* target = nullptr;
    for (const auto& candidate : targets_) {
        if (candidate->device.name == device) target = candidate.get();
    }
    if (!target) return make_error(ErrorKind::usage, fmt::format("no device \"{}\" on this gateway", device));
    if (assignments.empty()) return make_error(ErrorKind::usage, "no value given");
    std::vector<std::pair<const device::Parameter*, std::string>> planned;
    WrittenValues written;
    for (const auto& assignment : assignments) {
        // The CLI's resolution: names, aliases (PV, SP, OUT), then the manual's mnemonics.
        auto resolved = device::resolve_parameters(*target->device.address.profile, {assignment.parameter});
        if (!resolved) return make_error(ErrorKind::usage, fmt::format("device \"{}\": {}", device, resolved.error().message));
        if (resolved->size() != 1) {
            return make_error(ErrorKind::usage, fmt::format("device \"{}\": \"{}\" names {} parameters; write them one by one",
                                                            device, assignment.parameter, resolved->size()));
        }
        const device::Parameter* parameter = resolved->front();
        if (assignment.text.empty()) {
            return make_error(ErrorKind::usage, fmt::format("no value given for {}", parameter->name));
        }
        planned.emplace_back(parameter, assignment.text);
        written.values.emplace_back(parameter->name, assignment.text);
    }
    device::DeviceClient client(target->master, target->device.address);
    auto report = client.write(planned);
    if (!report) return client.explain(report.error());
    return written;
}

}  // namespace loopwire::gateway
