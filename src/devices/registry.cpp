#include "devices/registry.hpp"

#include <array>

#include "devices/ac20/ac20_restore_procedure.hpp"
#include "devices/ac20/ac20_simulator.hpp"
#include "devices/rampsoak/rampsoak_simulator.hpp"
#include "devices/tc10/tc10_simulator.hpp"

namespace loopwire::device::models {
namespace {

template <typename Simulator>
std::shared_ptr<SimulatedDevice> make(std::shared_ptr<const Profile> profile, SimulationEnvironment environment) {
    return std::make_shared<Simulator>(std::move(profile), std::move(environment));
}

const std::array<DeviceModel, 3>& device_models() {
    static const std::array<DeviceModel, 3> models{{
        {"ac20", make<Ac20Simulator>, plan_ac20_restore},
        {"tc10", make<Tc10Simulator>, {}},
        {"rampsoak", make<RampSoakSimulator>, {}},
    }};
    return models;
}

}  // namespace

const DeviceModel* find_device_model(std::string_view profile_id) {
    for (const DeviceModel& model : device_models()) {
        if (model.profile_id == profile_id) return &model;
    }
    return nullptr;
}

std::shared_ptr<SimulatedDevice> make_simulated_device(std::shared_ptr<const Profile> profile,
                                                       SimulationEnvironment environment) {
    if (const DeviceModel* model = find_device_model(profile->id)) return model->make_simulator(std::move(profile), std::move(environment));
    return std::make_shared<SimulatedDevice>(std::move(profile), std::move(environment));
}

RestoreProcedure restore_procedure_for(const Profile& profile) {
    const DeviceModel* model = find_device_model(profile.id);
    return model ? model->restore_procedure : RestoreProcedure{};
}

}  // namespace loopwire::device::models
