#include "device/models/rampsoak_simulator.hpp"

namespace loopwire::device::models {

RampSoakSimulator::RampSoakSimulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment)
    : SimulatedDevice(std::move(profile), std::move(environment)) {}

}  // namespace loopwire::device::models
