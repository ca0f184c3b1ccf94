#pragma once
// The ac20 behaviour model: what the manual says the device does beyond its profile data.
#include "device/simulated_device.hpp"

namespace loopwire::device::models {

class Ac20Simulator : public SimulatedDevice {
public:
    Ac20Simulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment);
};

}  // namespace loopwire::device::models
