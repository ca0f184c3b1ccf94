#include "device/models/ac20_simulator.hpp"

namespace loopwire::device::models {

Ac20Simulator::Ac20Simulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment)
    : SimulatedDevice(std::move(profile), std::move(environment)) {}

}  // namespace loopwire::device::models
