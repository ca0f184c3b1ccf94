#pragma once
// The furnace atmosphere an AC20 measures: an endothermic carrier gas (CO, H2, N2 with traces
// of CO2, H2O and O2) in which steel is carburised, read through a zirconia oxygen probe and a
// thermocouple. The AC20 shows three views of the same atmosphere (manual words 122-124: probe
// mV, carbon potential, dew point); they are tied together here by equilibrium thermodynamics,
// so a value read at one word can be checked against the others.
//
// Derivation (T in kelvin, partial pressures in atm):
//
// 1. Probe (Nernst, reference air pO2 = 0.209 atm, four electrons per O2):
//        E = (R T / 4 F) ln(0.209 / pO2)        E in volts
//    R/4F·ln10 = 4.9608e-5 V/K, so E[mV] = 0.049608 · T · log10(0.209 / pO2).
//
// 2. Carbon activity in the gas, from the Boudouard reaction 2 CO = C + CO2 (K1) and
//    CO + ½ O2 = CO2 (K2):
//        a_C = K1 pCO² / pCO2,   pCO2 = K2 pCO √pO2   ⇒   a_C = K1 pCO / (K2 √pO2)
//    with the standard Gibbs energies (J/mol; Kubaschewski-style linear fits)
//        ΔG1 = −170 700 + 174.5 T,   ΔG2 = −282 400 + 86.8 T,   K = exp(−ΔG / R T).
//
// 3. Carbon in austenite from its activity (Gunnarson's relation for plain carbon steel):
//        log10 a_C = log10 %C + 2300 / T − 2.21 + 0.15 %C
//    (a_C = 1, soot, near 1.25 %C at 925 °C: the Acm saturation limit).
//
// 4. Dew point, from the water-gas equilibrium H2 + ½ O2 = H2O (K3):
//        pH2O = K3 pH2 √pO2,   ΔG3 = −246 400 + 54.8 T,
//    and the Magnus formula over water (p in Pa): Td = 243.12 ln(p/611.2) / (17.62 − ln(p/611.2)).
//
// With 20 % CO and 40 % H2 (the AC20's CO and H2 factors, words 142/143) at 925 °C this gives
// 0.80 %C ↔ 1134 mV ↔ −5 °C dew point: the usual neighbourhood of a carburising atmosphere.
namespace loopwire::device::models::ac20 {

struct Gas {
    double carbon_monoxide = 0.20;  // CO fraction (word 142 "CO factor" in %)
    double hydrogen = 0.40;         // H2 fraction (word 143 "H2 factor" in %)
};

double kelvin(double celsius);

// Oxygen partial pressure (atm) of an atmosphere with carbon potential `carbon_percent`.
double oxygen_pressure_for_carbon(double carbon_percent, double temperature_celsius, const Gas& gas = {});
// The probe's output (mV) in an atmosphere with oxygen partial pressure `oxygen_pressure`.
double probe_millivolts(double oxygen_pressure, double temperature_celsius);
// The inverse: oxygen partial pressure (atm) that makes the probe read `millivolts`.
double oxygen_pressure_for_millivolts(double millivolts, double temperature_celsius);
// Carbon potential (%C) of an atmosphere with oxygen partial pressure `oxygen_pressure`.
double carbon_potential(double oxygen_pressure, double temperature_celsius, const Gas& gas = {});
// Dew point (°C) of an atmosphere with oxygen partial pressure `oxygen_pressure`.
double dew_point_celsius(double oxygen_pressure, double temperature_celsius, const Gas& gas = {});

// What the AC20 computes from its two inputs (probe mV, thermocouple °C).
struct ProbeReading {
    double carbon_percent = 0;
    double dew_point_celsius = 0;
};
ProbeReading read_probe(double millivolts, double temperature_celsius, const Gas& gas = {});

}  // namespace loopwire::device::models::ac20
