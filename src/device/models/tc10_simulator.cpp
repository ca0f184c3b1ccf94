#include "device/models/tc10_simulator.hpp"

namespace loopwire::device::models {

Tc10Simulator::Tc10Simulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment)
    : SimulatedDevice(std::move(profile), std::move(environment)) {}

}  // namespace loopwire::device::models
