#pragma once
// `loopwire simulate --state FILE`: what each simulated device keeps in non-volatile memory,
// across restarts. RAM-only values (AC20 word 137, TC10 remote set point, ramp/soak values
// changed by Linking M) are not in it, as the manuals say they are lost at power-off.
//
//   {"format": "loopwire-simulator-state", "version": 1,
//    "units": {"3": {"profile": "tc10", "saved": {"set_point": 150, ...}}, ...}}
//
// A unit may also have "condition": {"mode": 1, "remote": 1}, what the device was doing at
// power-off besides its parameters (the AC20 keeps its configuration or security code mode and
// its local/remote state, Note 5). Files without it load as before: the device powers up as
// it does with no file.
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
    // values. A file that is not a state file, or that has a value of the wrong type, is an
    // error naming its JSON pointer (and is never overwritten); so is a file that could not be
    // saved (found now, before anything is served, not at the first acknowledged write). A unit
    // kept for another profile, names the profile lacks, and temporaries left by a writer that
    // was killed (removed) are warnings.
    static Result<SimulatorStateFile> open(const std::string& path, const Devices& devices);

    // Writes the file if any device's saved contents changed since the last successful save;
    // after a failed save the change stays pending, so the next call tries again.
    Result<void> save_if_changed();
    bool has_unsaved_changes() const;

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

// Checks a state file's text as open() does; `path` only names it in errors.
Result<nlohmann::json> parse_state_text(const std::string& text, const std::string& path);

}  // namespace loopwire::device
