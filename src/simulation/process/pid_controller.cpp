#include "simulation/process/pid_controller.hpp"

#include <algorithm>

namespace loopwire::device::process {
namespace {

double gain_of(const PidSettings& settings) { return 100.0 / (settings.proportional_band * settings.span / 100.0); }

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
    const double rate = (started_ && seconds > 0) ? (pv - last_pv_) / seconds : 0.0;
    last_pv_ = pv;
    started_ = true;
    const double derivative = settings_.derivative_time * rate;
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
    started_ = true;
    if (settings_.proportional_band > 0) integral_ = output / gain_of(settings_) - (sp - pv);
}

}  // namespace loopwire::device::process
