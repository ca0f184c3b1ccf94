#pragma once
// The simulated device for a profile: the behaviour model written for it (AC20, TC10,
// ramp/soak), or the plain profile-driven simulator for a profile that has none (a new device
// is a new JSON file first; DESIGN.md).
#include <memory>

#include "device/simulated_device.hpp"

namespace loopwire::device::models {

std::shared_ptr<SimulatedDevice> make_simulated_device(std::shared_ptr<const Profile> profile,
                                                       SimulationEnvironment environment = {});

}  // namespace loopwire::device::models
