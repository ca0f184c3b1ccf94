#include "simulation/process/pid_controller.hpp"

#include <algorithm>
#include <cmath>

namespace loopwire::device::process {
namespace {

double gain_of(const PidSettings& settings) { return 100.0 / (settings.proportional_band * settings.span / 100.0); }

// The derivative filter's time constant is Td / derivative_filter_ratio.
constexpr double derivative_filter_ratio = 8.0;

// The measured rate after a first-order filter of time constant Td / 8, stepped over `seconds`
// (exact for a rate held constant over the step, so the result does not depend on step size).
double filtered_rate(double previous, double raw, double seconds, double derivative_time) {
    const double time_constant = derivative_time / derivative_filter_ratio;
    if (time_constant <= 0) return raw;
    return raw + (previous - raw) * std::exp(-seconds / time_constant);
}

}  // namespace

double PidController::step(double seconds, double sp, double pv) {
    const double error = sp - pv;
    if (settings_.proportional_band <= 0) {
        // On/off: full output below SP - hysteresis, none above SP, unchanged between.
        if (pv < sp - settings_.hysteresis) output_ = settings_.output_high;
        if (pv >= sp) output_ = settings_.output_low;
        last_pv_ = pv;
        started_ = true;
        return output_;
    }
    const double gain = gain_of(settings_);
    if (started_ && seconds > 0) rate_ = filtered_rate(rate_, (pv - last_pv_) / seconds, seconds, settings_.derivative_time);
    last_pv_ = pv;
    started_ = true;
    const double derivative = settings_.derivative_time * rate_;
    double candidate_integral = integral_;
    if (settings_.integral_time > 0 && seconds > 0) candidate_integral += error * seconds / settings_.integral_time;
    const double unclamped = gain * (error + candidate_integral - derivative);
    const double clamped = std::clamp(unclamped, settings_.output_low, settings_.output_high);
    // Anti-windup: the integral moves only while it does not push further into saturation.
    const bool winding_up = (unclamped > settings_.output_high && error > 0) || (unclamped < settings_.output_low && error < 0);
    if (!winding_up) integral_ = candidate_integral;
    output_ = clamped;
    return output_;
}

void PidController::track(double output, double sp, double pv) {
    output_ = output;
    last_pv_ = pv;
    rate_ = 0;
    started_ = true;
    if (settings_.proportional_band > 0) integral_ = output / gain_of(settings_) - (sp - pv);
}

}  // namespace loopwire::device::process
