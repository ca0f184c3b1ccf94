#pragma once
// The device models loopwire has code for, by profile id: what a profile's data cannot express
// (docs/DESIGN.md, "Device knowledge is data"). Each model is registered here explicitly, once;
// nothing is chosen by looking at parameter names. A profile with no model (a run-time profile
// file, a new device) is simulated from its data alone and restored in the generic order.
#include <functional>
#include <memory>
#include <string_view>

#include "client/restore_plan.hpp"
#include "simulation/simulated_device.hpp"

namespace loopwire::device::models {

using SimulatorFactory =
    std::function<std::shared_ptr<SimulatedDevice>(std::shared_ptr<const Profile> profile, SimulationEnvironment environment)>;

struct DeviceModel {
    std::string_view profile_id;
    SimulatorFactory make_simulator;       // its behaviour model (simulation side)
    RestoreProcedure restore_procedure;    // empty: the generic bound-safe order (master side)
};

// The model registered for `profile_id`, or nullptr.
const DeviceModel* find_device_model(std::string_view profile_id);

// The simulated device for a profile: its model's simulator, or the plain profile-driven one.
std::shared_ptr<SimulatedDevice> make_simulated_device(std::shared_ptr<const Profile> profile,
                                                       SimulationEnvironment environment = {});

// The restore procedure for a profile: its model's, or empty for the generic order.
RestoreProcedure restore_procedure_for(const Profile& profile);

}  // namespace loopwire::device::models
