#pragma once
// The tc10 behaviour model: what the manual says the device does beyond its profile data.
#include "device/simulated_device.hpp"

namespace loopwire::device::models {

class Tc10Simulator : public SimulatedDevice {
public:
    Tc10Simulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment);
};

}  // namespace loopwire::device::models
