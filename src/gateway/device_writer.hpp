#pragma once
// Writes by parameter name for the gateway's fronts (MQTT, HTTP): the same checks as the CLI's
// `write` (access, type, decimals, range, the device's mode), then the planned requests, sent
// through the device's line scheduler at Priority::write so they go before the polls.
//
// Threads: write() blocks its caller until the line has answered; call it from a front's own
// worker, never from a network loop. Several fronts may write at once (the schedulers queue).
#include <chrono>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "client/device_client.hpp"
#include "common/result.hpp"
#include "gateway/line_scheduler.hpp"

namespace loopwire::gateway {

// A device the fronts may write to: its configured name, profile and unit, and its line.
struct WritableDevice {
    std::string name;
    device::DeviceAddress address;
    std::shared_ptr<LineScheduler> line;
};

// One value to write: the parameter's name (or mnemonic, or alias) and the text a user gives
// the CLI ("150", "on").
struct WriteAssignment {
    std::string parameter;
    std::string text;
};

// What was written: each parameter's profile name and the text it was given, in order.
struct WrittenValues {
    std::vector<std::pair<std::string, std::string>> values;
};

class DeviceWriter {
public:
    // `write_limit`: how long a write may wait for its line before it is given up.
    DeviceWriter(std::vector<WritableDevice> devices, std::chrono::milliseconds write_limit);
    ~DeviceWriter();
    DeviceWriter(const DeviceWriter&) = delete;
    DeviceWriter& operator=(const DeviceWriter&) = delete;

    // The device of that configured name, or nullptr.
    const WritableDevice* find(const std::string& name) const;

    // Validates every assignment, then writes them in planned blocks; nothing is sent when one
    // is invalid. The error says which name or value was wrong, or how the device refused, in
    // words (the profile's meaning of the exception code).
    Result<WrittenValues> write(const std::string& device, const std::vector<WriteAssignment>& assignments) const;

private:
    struct Target;
    std::vector<std::unique_ptr<Target>> targets_;
};

}  // namespace loopwire::gateway
