#pragma once
// The units `loopwire simulate` serves: plain register banks (--unit N) and simulated devices
// from their profiles (--device DEVICE@UNIT).
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "profile/profile_registry.hpp"
#include "simulation/simulated_device.hpp"
#include "session/slave.hpp"
#include "transport/link_url.hpp"

namespace loopwire::device::models {

struct SimulatedUnits {
    session::UnitMap units;
    std::map<std::uint8_t, std::shared_ptr<SimulatedDevice>> devices;  // the --device ones
    std::vector<std::string> descriptions;  // one line per unit: "3: tc10 (Yokogawa TC10 ...)"
    std::vector<std::string> warnings;      // link settings the real device cannot have
};

// A unit named twice, or a device id not in `profiles`, is a usage error. With neither list given, unit 1
// is a plain bank.
// Each device gets its own copy of `environment` (its framing taken from the link).
Result<SimulatedUnits> build_simulated_units(const ProfileRegistry& profiles, const std::vector<int>& bank_units, const std::vector<std::string>& devices,
                                             const transport::LinkUrl& link,
                                             const SimulationEnvironment& environment = {});

// --fault DEVICE@UNIT:FAULT on the units built above: the unit must be a simulated device of
// that profile, and the fault one it knows.
Result<void> apply_fault_option(SimulatedUnits& units, const std::string& option);

}  // namespace loopwire::device::models
