#include "device/models/simulator_factory.hpp"

#include "device/models/ac20_simulator.hpp"
#include "device/models/rampsoak_simulator.hpp"
#include "device/models/tc10_simulator.hpp"

namespace loopwire::device::models {

std::shared_ptr<SimulatedDevice> make_simulated_device(std::shared_ptr<const Profile> profile,
                                                       SimulationEnvironment environment) {
    const std::string id = profile->id;
    if (id == "ac20") return std::make_shared<Ac20Simulator>(std::move(profile), std::move(environment));
    if (id == "tc10") return std::make_shared<Tc10Simulator>(std::move(profile), std::move(environment));
    if (id == "rampsoak") return std::make_shared<RampSoakSimulator>(std::move(profile), std::move(environment));
    return std::make_shared<SimulatedDevice>(std::move(profile), std::move(environment));
}

}  // namespace loopwire::device::models
