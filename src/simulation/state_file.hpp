#pragma once
// `loopwire simulate --state FILE`: what each simulated device keeps in non-volatile memory,
// across restarts. RAM-only values (AC20 word 137, TC10 remote set point, ramp/soak values
// changed by Linking M) are not in it, as the manuals say they are lost at power-off.
//
//   {"format": "loopwire-simulator-state", "version": 1,
//    "units": {"3": {"profile": "tc10", "saved": {"set_point": 150, ...}}, ...}}
//
// Units in the file that this run does not serve are kept as they are.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/result.hpp"
#include "simulation/simulated_device.hpp"

namespace loopwire::device {

class SimulatorStateFile {
public:
    using Devices = std::map<std::uint8_t, std::shared_ptr<device::SimulatedDevice>>;

    // Reads `path` (a missing file is an empty state) and loads each served device's saved
    // values. A file that is not a state file is an error (and is never overwritten); a unit
    // kept for another profile, or names the profile lacks, are warnings.
    static Result<SimulatorStateFile> open(const std::string& path, const Devices& devices);

    // Writes the file if any device's saved contents changed since the last save.
    Result<void> save_if_changed();

    const std::vector<std::string>& warnings() const { return warnings_; }

private:
    SimulatorStateFile(std::string path, Devices devices) : path_(std::move(path)), devices_(std::move(devices)) {}
    Result<void> load(const nlohmann::json& document);
    Result<void> save();

    std::string path_;
    Devices devices_;
    nlohmann::json document_ = nlohmann::json::object();
    std::map<std::uint8_t, std::uint64_t> saved_generations_;
    std::vector<std::string> warnings_;
};

}  // namespace loopwire::device
