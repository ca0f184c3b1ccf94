#include "devices/tc10/tc10_alarms.hpp"

namespace loopwire::device::models::tc10 {
namespace {

// HALn is the distance the measurement must come back before an alarm that is on goes off
// (§5.3.3 #33), so an alarm does not chatter around its threshold.
bool below(double measured, double threshold, double hysteresis, bool was_on) {
    return was_on ? measured < threshold + hysteresis : measured <= threshold;
}

bool above(double measured, double threshold, double hysteresis, bool was_on) {
    return was_on ? measured > threshold - hysteresis : measured >= threshold;
}

bool outside(double measured, double low, double high, double hysteresis, bool was_on) {
    return below(measured, low, hysteresis, was_on) || above(measured, high, hysteresis, was_on);
}

bool inside(double measured, double low, double high, double hysteresis, bool was_on) {
    return was_on ? measured > low - hysteresis && measured < high + hysteresis : measured >= low && measured <= high;
}

bool is_relative(AlarmType type) {
    return type == AlarmType::deviation_low || type == AlarmType::deviation_high ||
           type == AlarmType::relative_band_outside || type == AlarmType::relative_band_inside;
}

}  // namespace

// §5.3.3 #28 names the types; the manual does not define where a relative threshold lies.
// Chosen: a deviation alarm's threshold is SP + ALn and a relative band is
// [SP + ALnL, SP + ALnH] (ALn and ALnL may be negative), the absolute band is [ALnL, ALnH]
// ("для сигнализации зоны является нижним/верхним порогом", #30/#31).
bool Alarm::condition(const AlarmSettings& settings, const AlarmInputs& inputs) const {
    const double pv = inputs.measured;
    const double h = settings.hysteresis;
    const double sp = inputs.set_point;
    switch (settings.type) {
        case AlarmType::absolute_low: return below(pv, settings.threshold, h, condition_);
        case AlarmType::absolute_high: return above(pv, settings.threshold, h, condition_);
        case AlarmType::band_outside: return outside(pv, settings.low_limit, settings.high_limit, h, condition_);
        case AlarmType::band_inside: return inside(pv, settings.low_limit, settings.high_limit, h, condition_);
        case AlarmType::sensor_break: return inputs.measurement_error;
        case AlarmType::deviation_low: return below(pv, sp + settings.threshold, h, condition_);
        case AlarmType::deviation_high: return above(pv, sp + settings.threshold, h, condition_);
        case AlarmType::relative_band_outside:
            return outside(pv, sp + settings.low_limit, sp + settings.high_limit, h, condition_);
        case AlarmType::relative_band_inside:
            return inside(pv, sp + settings.low_limit, sp + settings.high_limit, h, condition_);
        case AlarmType::none: break;
    }
    return false;
}

void Alarm::update(double seconds, const AlarmSettings& settings, const AlarmInputs& inputs) {
    // ALno (#35): "0 = alarm disabled in standby and in the out-of-range state". An inhibited
    // alarm is off altogether, latch included. A sensor-break alarm exists for the
    // out-of-range state, so only standby inhibits it.
    const bool inhibited_by_standby = inputs.standby && (settings.enable & enabled_in_standby) == 0;
    const bool inhibited_by_error = inputs.measurement_error && settings.type != AlarmType::sensor_break &&
                                    (settings.enable & enabled_out_of_range) == 0;
    if (settings.type == AlarmType::none || inhibited_by_standby || inhibited_by_error) {
        clear();
        started_ = true;  // power-on is over even for an alarm that is off
        last_set_point_ = inputs.set_point;
        return;
    }
    condition_ = condition(settings, inputs);
    update_mask(settings, inputs);
    // ALnd (#34): the condition must last the delay before the alarm is raised.
    held_ = condition_ ? held_ + seconds : 0;
    raised_ = condition_ && !masked_ && held_ >= settings.delay;
    if (raised_ && (settings.function & function_latched) != 0) latched_ = true;
    // An acknowledgement lasts until the alarm is over; the next occurrence alarms again.
    if (!raised_ && !latched_) acknowledged_ = false;
}

// Abn +1 "не активна при включении питания" and +8 "относительная сигнализация не активна при
// изменении уставки" (#29): after power-on, or after the set point moves under a relative
// alarm, an alarm condition already present is ignored until the process has once left it
// (the usual start-up masking: an oven starting cold must not raise its low alarm).
void Alarm::update_mask(const AlarmSettings& settings, const AlarmInputs& inputs) {
    if (!started_ && (settings.function & function_masked_at_power_on) != 0) masked_ = true;
    if (started_ && inputs.set_point != last_set_point_ && is_relative(settings.type) &&
        (settings.function & function_masked_at_sp_change) != 0) {
        masked_ = true;
    }
    started_ = true;
    last_set_point_ = inputs.set_point;
    if (!condition_) masked_ = false;
}

void Alarm::reset() {
    if (!raised_) latched_ = false;
}

void Alarm::acknowledge(std::uint16_t function) {
    if ((function & function_acknowledgeable) != 0 && (raised_ || latched_)) acknowledged_ = true;
}

void Alarm::clear() {
    condition_ = raised_ = latched_ = acknowledged_ = masked_ = false;
    held_ = 0;
}

}  // namespace loopwire::device::models::tc10
