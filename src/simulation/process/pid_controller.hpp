#pragma once
// A PID controller as process controllers implement it: proportional band in percent of a
// span, integral and derivative times in seconds, output limited to 0..100 % with the
// integral frozen while the output is saturated (anti-windup), derivative on the measurement
// so a set-point step does not kick the output.
//
//
//     e = SP - PV,   Kp = 100 / (PB% * span / 100)   (% output per engineering unit)
//     out% = Kp * (e + I - Td * dPV/dt),   dI/dt = e / Ti
//
// The derivative is filtered over Td / 8 (the usual first-order filter of industrial PIDs; none
// of the manuals gives one): unfiltered, a measurement that moves in display counts turns every
// one-count step into a spike that drives the output to a limit, and the loop cycles.
//
// With PB = 0 the controller is on/off with a hysteresis below SP.
namespace loopwire::device::process {

struct PidSettings {
    double proportional_band = 5.0;  // % of span; 0 = on/off control
    double integral_time = 240.0;    // s; 0 = no integral action
    double derivative_time = 60.0;   // s; 0 = no derivative action
    double span = 1000.0;            // engineering units the band is a percentage of
    double output_low = 0.0;         // %
    double output_high = 100.0;      // %
    double hysteresis = 0.5;         // engineering units, on/off control only
};

class PidController {
public:
    explicit PidController(PidSettings settings = {}) : settings_(settings) {}

    // The output in percent after `seconds` with set point `sp` and measurement `pv`.
    double step(double seconds, double sp, double pv);

    // Bumpless transfer from manual: the next automatic output starts at `output`.
    void track(double output, double sp, double pv);

    void set_settings(const PidSettings& settings) { settings_ = settings; }
    const PidSettings& settings() const { return settings_; }
    double output() const { return output_; }

private:
    PidSettings settings_;
    double integral_ = 0;  // in engineering units (error × s / Ti)
    double last_pv_ = 0;
    double rate_ = 0;      // dPV/dt after the derivative filter, units per second
    bool started_ = false;
    double output_ = 0;
};

}  // namespace loopwire::device::process
