#include "devices/ac20/ac20_atmosphere.hpp"

#include <algorithm>
#include <cmath>

namespace loopwire::device::models::ac20 {
namespace {

constexpr double gas_constant = 8.314;              // J/(mol K)
constexpr double nernst_mv_per_kelvin = 0.049608;   // 1000 · R ln10 / 4F
constexpr double reference_oxygen = 0.209;          // air on the probe's reference side

double equilibrium(double enthalpy, double entropy, double t_kelvin) {
    return std::exp(-(enthalpy + entropy * t_kelvin) / (gas_constant * t_kelvin));
}
double boudouard(double t) { return equilibrium(-170700.0, 174.5, t); }       // 2CO = C + CO2
double co_oxidation(double t) { return equilibrium(-282400.0, 86.8, t); }     // CO + ½O2 = CO2
double h2_oxidation(double t) { return equilibrium(-246400.0, 54.8, t); }     // H2 + ½O2 = H2O

// Gunnarson: log10 a_C = log10 %C + 2300/T − 2.21 + 0.15 %C.
double activity_of(double carbon_percent, double t) {
    return std::pow(10.0, std::log10(carbon_percent) + 2300.0 / t - 2.21 + 0.15 * carbon_percent);
}

// Inverse of activity_of: log10 c + 0.15 c is increasing in c, so Newton's method from 1 %C
// converges; the result is clamped away from 0 so a very lean atmosphere stays finite.
double carbon_of(double activity, double t) {
    const double target = std::log10(activity) - 2300.0 / t + 2.21;
    double c = 1.0;
    for (int i = 0; i < 50; ++i) {
        const double f = std::log10(c) + 0.15 * c - target;
        const double slope = 1.0 / (c * std::log(10.0)) + 0.15;
        const double next = std::max(1e-6, c - f / slope);
        if (std::abs(next - c) < 1e-12) return next;
        c = next;
    }
    return c;
}

}  // namespace

double kelvin(double celsius) { return celsius + 273.15; }

double oxygen_pressure_for_carbon(double carbon_percent, double temperature_celsius, const Gas& gas) {
    const double t = kelvin(temperature_celsius);
    const double root = boudouard(t) * gas.carbon_monoxide / (co_oxidation(t) * activity_of(carbon_percent, t));
    return root * root;
}

double probe_millivolts(double oxygen_pressure, double temperature_celsius) {
    return nernst_mv_per_kelvin * kelvin(temperature_celsius) * std::log10(reference_oxygen / oxygen_pressure);
}

double oxygen_pressure_for_millivolts(double millivolts, double temperature_celsius) {
    return reference_oxygen / std::pow(10.0, millivolts / (nernst_mv_per_kelvin * kelvin(temperature_celsius)));
}

double carbon_potential(double oxygen_pressure, double temperature_celsius, const Gas& gas) {
    const double t = kelvin(temperature_celsius);
    const double activity = boudouard(t) * gas.carbon_monoxide / (co_oxidation(t) * std::sqrt(oxygen_pressure));
    return carbon_of(activity, t);
}

double dew_point_celsius(double oxygen_pressure, double temperature_celsius, const Gas& gas) {
    const double t = kelvin(temperature_celsius);
    const double water_pa = h2_oxidation(t) * gas.hydrogen * std::sqrt(oxygen_pressure) * 101325.0;
    const double g = std::log(water_pa / 611.2);
    return 243.12 * g / (17.62 - g);
}

ProbeReading read_probe(double millivolts, double temperature_celsius, const Gas& gas) {
    const double oxygen = oxygen_pressure_for_millivolts(millivolts, temperature_celsius);
    return {carbon_potential(oxygen, temperature_celsius, gas), dew_point_celsius(oxygen, temperature_celsius, gas)};
}

}  // namespace loopwire::device::models::ac20
