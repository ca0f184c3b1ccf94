#include "simulation/process/thermal_plant.hpp"

#include <algorithm>
#include <cmath>

namespace loopwire::device::process {

ThermalPlant::ThermalPlant(ThermalPlantSettings settings)
    : settings_(settings), temperature_(settings.ambient) {}

double ThermalPlant::delayed_output() const { return arrived_output_; }

void ThermalPlant::step(double seconds, double output) {
    if (seconds <= 0) return;
    in_transit_.emplace_back(time_, std::clamp(output, settings_.lowest_output, 1.0));
    time_ += seconds;
    // Outputs older than the dead time have reached the sensor; the newest of them acts now.
    while (!in_transit_.empty() && in_transit_.front().first <= time_ - settings_.dead_time) {
        arrived_output_ = in_transit_.front().second;
        in_transit_.pop_front();
    }
    // Exact solution of the linear ODE over the step (stable for any step length).
    const double target = settings_.ambient + settings_.gain * delayed_output();
    const double decay = std::exp(-seconds / settings_.time_constant);
    temperature_ = target + (temperature_ - target) * decay;
}

}  // namespace loopwire::device::process
