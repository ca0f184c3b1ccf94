#pragma once
// A heated chamber (furnace, oven) as a first-order lag with dead time and heat loss:
//
//     dT/dt = (gain * u(t - dead_time) - (T - ambient)) / time_constant
//
// u is the heating output as a fraction 0..1. At a steady output u the chamber settles at
// ambient + gain * u: the loss to the surroundings, proportional to T - ambient, balances the
// heat put in. The dead time is the transport delay between the heater and the sensor.
#include <deque>

namespace loopwire::device::process {

struct ThermalPlantSettings {
    double ambient = 25.0;        // °C
    double gain = 1000.0;         // °C above ambient at 100 % output, steady state
    double time_constant = 600.0; // s
    double dead_time = 20.0;      // s
    double lowest_output = 0.0;   // below 0 a cooler draws heat out: -1 cools as hard as gain heats
};

class ThermalPlant {
public:
    explicit ThermalPlant(ThermalPlantSettings settings = {});

    // Advances by `seconds` with heating output `output` (lowest_output..1, clamped) applied from now on.
    void step(double seconds, double output);

    double temperature() const { return temperature_; }
    void set_temperature(double temperature) { temperature_ = temperature; }
    const ThermalPlantSettings& settings() const { return settings_; }

private:
    double delayed_output() const;

    ThermalPlantSettings settings_;
    double temperature_;
    double time_ = 0;
    // (time applied, output): outputs still travelling through the dead time, oldest first.
    std::deque<std::pair<double, double>> in_transit_;
    double arrived_output_ = 0;
};

}  // namespace loopwire::device::process
