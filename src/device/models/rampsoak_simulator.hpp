#pragma once
// The rampsoak behaviour model: what the manual says the device does beyond its profile data.
#include "device/simulated_device.hpp"

namespace loopwire::device::models {

class RampSoakSimulator : public SimulatedDevice {
public:
    RampSoakSimulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment);
};

}  // namespace loopwire::device::models
