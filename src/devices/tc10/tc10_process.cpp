// The process a TC10 controls: the oven (thermal plant), the PID driven by Pb/ti/td, the
// control states' effect on the output, the alarms and the input faults.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "devices/tc10/tc10_simulator.hpp"

namespace loopwire::device::models {
namespace {

double signed_raw(std::uint16_t raw) { return static_cast<std::int16_t>(raw); }

// The display range in counts (-1999…9999, the limits of the §5.3 numeric parameters): a
// temperature beyond it cannot be shown and reads as out of range (§5.1 1A).
constexpr double lowest_counts = -1999;
constexpr double highest_counts = 9999;

struct AlarmNames {
    std::string_view type, function, low, high, threshold, hysteresis, delay, enable;
};

constexpr std::array<AlarmNames, 3> alarm_names{{
    {"alarm_1_type", "alarm_1_function", "alarm_1_low_limit", "alarm_1_high_limit", "alarm_1_threshold",
     "alarm_1_hysteresis", "alarm_1_delay", "alarm_1_standby_overrange_enable"},
    {"alarm_2_type", "alarm_2_function", "alarm_2_low_limit", "alarm_2_high_limit", "alarm_2_threshold",
     "alarm_2_hysteresis", "alarm_2_delay", "alarm_2_standby_overrange_enable"},
    {"alarm_3_type", "alarm_3_function", "alarm_3_low_limit", "alarm_3_high_limit", "alarm_3_threshold",
     "alarm_3_hysteresis", "alarm_3_delay", "alarm_3_standby_overrange_enable"},
}};

// The oven has a heater; a cooling (negative) output drives a cooler a quarter as strong.
constexpr double cooler_share = 0.25;

constexpr std::array<std::string_view, 4> output_functions{"output_1_function", "output_2_function",
                                                           "output_3_function", "output_4_function"};
constexpr std::uint16_t function_heating = 1;  // o<n>F H.rEG (§5.3.2 #14)
constexpr std::uint16_t function_cooling = 2;  // o<n>F c.rEG

constexpr std::array<std::string_view, 4> local_set_points{"set_point", "set_point_2", "set_point_3", "set_point_4"};

}  // namespace

std::vector<std::string> Tc10Simulator::fault_names() const {
    return {"open-input", "short-input", "adc-overflow", "loop-break", "output-4-overload"};
}

// One fault at a time; a new one (or "none") replaces the last.
// §5.1 1A lists the measurement errors: an open (burnt-out) sensor reads over-range, a shorted
// one under-range (both sent as 10000), an A/D overflow as 10001.
// "loop-break" opens the loop the LBA watches (§5.3.6): the heater (or cooler) is disconnected,
// so the control output no longer reaches the oven and the measurement does not answer it.
// "output-4-overload" overloads output 4 (§5.3.2 #17 "+32 = Перегрузка на выходе 4", overload
// on output 4; §5.2 11B).
void Tc10Simulator::apply_fault(const std::string& fault) {
    fault_ = InputFault::none;
    loop_open_ = fault == "loop-break";
    overloaded_ = fault == "output-4-overload";
    if (fault == "open-input") fault_ = InputFault::over_range;
    else if (fault == "short-input") fault_ = InputFault::under_range;
    else if (fault == "adc-overflow") fault_ = InputFault::adc_overflow;
}

void Tc10Simulator::step_process(double seconds) {
    power_on();
    const StepSettings& settings = step_settings();
    const double set_point = step_ramp(seconds, settings);
    output_ = next_output(seconds, settings, set_point);
    const double drive = output_ >= 0 ? output_ / 100.0 : output_ / 100.0 * cooler_share;
    plant_.step(seconds, loop_open_ ? 0.0 : drive);
    update_alarms(seconds, settings, set_point);
    const Measurement measured = measurement(settings.scale);
    loop_break_.update(seconds, settings.loop_break, output_,
                       measured.fault == InputFault::none ? std::optional<double>(measured.value) : std::nullopt);
}

// The working set point for this step (§5.1 3A). The ramp runs in automatic only; manual and
// standby do not control to a set point. The manual does not say where a ramp starts. Chosen:
// at power-on and on each return to automatic it starts from the measured value (from the
// final set point while the measurement is in error), so the process is taken to the set
// point at the ramp's rate instead of by a step.
double Tc10Simulator::step_ramp(double seconds, const StepSettings& settings) {
    if (settings.state != State::automatic) {
        ramp_.restart();
        return settings.final_set_point;
    }
    const Measurement measured = measurement(settings.scale);
    const double start = measured.fault == InputFault::none ? measured.value : settings.final_set_point;
    ramp_.step(seconds, settings.final_set_point, start, settings.ramp);
    return *ramp_.working();
}

const Tc10Simulator::StepSettings& Tc10Simulator::step_settings() {
    if (step_settings_time_ == process_time()) return step_settings_;
    step_settings_time_ = process_time();
    StepSettings& settings = step_settings_;
    settings.state = state();
    settings.scale = scale();
    settings.final_set_point = final_set_point();
    settings.ramp = ramp_rates();
    settings.manual_output = signed_raw(value("manual_output_power")) / 100.0;
    settings.error_output = signed_raw(value("error_output_power"));
    settings.error_mode = value("sensor_error_mode");
    settings.pid = pid_settings();
    for (std::size_t i = 0; i < settings.alarms.size(); ++i) settings.alarms[i] = alarm_settings(i);
    settings.loop_break = loop_break_settings();
    pid_.set_settings(settings.pid);
    return settings;
}

// dP (#2) gives the decimals of every value marked dP: raw counts = units × 10^dP.
double Tc10Simulator::scale() const { return std::pow(10.0, std::clamp<int>(value("decimal_point"), 0, 3)); }

double Tc10Simulator::engineering(std::string_view name) const { return signed_raw(value(name)) / scale(); }

Tc10Simulator::Measurement Tc10Simulator::measurement(double scale) const {
    if (fault_ != InputFault::none) return {fault_, 0};
    const double counts = std::round(plant_.temperature() * scale);
    if (counts > highest_counts) return {InputFault::over_range, 0};
    if (counts < lowest_counts) return {InputFault::under_range, 0};
    return {InputFault::none, counts / scale};
}

bool Tc10Simulator::remote_set_point_in_use() const { return value("local_remote_set_point") == 1; }

// SPLr (#85) = rEn uses the remote set point of word 16 (§5.1 16A): SP.rt (#84) 0 = RSP as is,
// 1 = trin added to the local set point A.SP selects. 2 = PErc (scaled over the input range)
// is not simulated and is taken as RSP. This is the final set point; the ramp (SP.u, SP.d)
// leads the working one to it.
double Tc10Simulator::final_set_point() const {
    const double local = engineering(local_set_points[std::min<std::size_t>(value("active_set_point"), 3)]);
    if (!remote_set_point_in_use()) return local;
    const double remote = engineering("remote_set_point");
    return value("remote_set_point_type") == 1 ? local + remote : remote;
}

// §5.1 3A "Рабочая уставка" (working set point): where the ramp has got to, or the final set
// point when no ramp limits the change.
double Tc10Simulator::working_set_point() const {
    const double target = final_set_point();
    const tc10::RampRates rates = ramp_rates();
    if ((!rates.up && !rates.down) || state() != State::automatic) return target;
    return ramp_.working().value_or(target);
}

// §5.3.8 #86 SP.u / #87 SP.d: "0.01 … 99.99 (inF) ед. измерения в минуту", two fixed decimals
// (units per minute, whatever dP is). The top value 99.99 (raw 9999) reads as inF: no limit,
// the working set point steps to the new value (profiles/NOTES.md).
tc10::RampRates Tc10Simulator::ramp_rates() const {
    constexpr std::uint16_t infinite = 9999;
    const auto rate = [this](std::string_view name) -> std::optional<double> {
        const auto raw = static_cast<std::int16_t>(value(name));
        if (raw <= 0 || raw >= infinite) return std::nullopt;
        return raw / 100.0;
    };
    return {rate("ramp_up_rate"), rate("ramp_down_rate")};
}

// §5.1 12A bit 9 "Выполняется линейное изменение для уставки (повышение или понижение)": a
// set-point ramp is running (rising or falling).
bool Tc10Simulator::ramp_running() const {
    const tc10::RampRates rates = ramp_rates();
    return (rates.up || rates.down) && state() == State::automatic && ramp_.running(final_set_point());
}

// §5.3.6 #52 LbAt, #54 LbAS (dP), #55 LbcA; LbAS 0 (below its range, e.g. never written) counts
// as one display count.
tc10::LoopBreakSettings Tc10Simulator::loop_break_settings() const {
    tc10::LoopBreakSettings settings;
    settings.time = signed_raw(value("loop_break_alarm_time"));
    settings.delta = std::max(engineering("loop_break_delta"), 1.0 / scale());
    settings.condition = value("loop_break_condition");
    return settings;
}

// cont (#56): 0 = PID with Pb in engineering units (#62; a span of 100 makes the controller's
// percent band equal to units), ti and td in seconds, 0 = off (#63, #64); 1–3 = on/off with
// hysteresis HSEt (#60).
// The control action follows the outputs' functions (§5.3.2 #14: 1 = H.rEG "Выход нагрева",
// heating output; 2 = c.rEG "Выход охлаждения", cooling output; cont 0 = "ПИД (нагрев и
// охлаждение)"). Heating is reverse action: the output (0…100 %) rises as PV falls below SP.
// Cooling is direct action: the output (0…-100 %, §5.2 5B reads it as 0…100 %) rises as PV
// goes above SP. With both, the output runs -100…100 %; with neither, it is heating.
process::PidSettings Tc10Simulator::pid_settings() const {
    process::PidSettings settings = pid_.settings();
    const bool on_off = value("control_type") != 0;
    settings.span = 100.0;
    settings.proportional_band = on_off ? 0.0 : std::max(engineering("proportional_band"), 1.0 / scale());
    settings.hysteresis = engineering("on_off_hysteresis");
    settings.integral_time = signed_raw(value("integral_time"));
    settings.derivative_time = signed_raw(value("derivative_time"));
    bool heating = false, cooling = false;
    for (const std::string_view function : output_functions) {
        heating = heating || value(function) == function_heating;
        cooling = cooling || value(function) == function_cooling;
    }
    settings.output_low = cooling ? -100.0 : 0.0;
    settings.output_high = heating || !cooling ? 100.0 : 0.0;
    return settings;
}

// §5.3.10 #130: automatic runs the PID; manual (oPLo) holds the manual output (§5.2 28B);
// standby turns the control outputs off. On a measurement error in automatic the output is the
// one of §5.1 18A when inE (#7: 0 or, 1 ou, 2 ouf) covers the error, else 0; an A/D overflow
// counts as over-range. Manual and the error output keep the PID tracking for a bumpless return.
double Tc10Simulator::next_output(double seconds, const StepSettings& settings, double set_point) {
    const Measurement measured = measurement(settings.scale);
    double output = 0;
    if (settings.state == State::manual) {
        output = settings.manual_output;
    } else if (settings.state == State::automatic && measured.fault != InputFault::none) {
        const bool under = measured.fault == InputFault::under_range;
        if (settings.error_mode == 2 || (settings.error_mode == 1) == under) output = settings.error_output;
    } else if (settings.state == State::automatic) {
        return pid_.step(seconds, set_point, measured.value);
    } else {
        // Out of standby the controller starts afresh, as at power-on: tracking a zero output
        // against a large error would wind the integral far below what the oven needs.
        pid_ = process::PidController(settings.pid);
        return 0;
    }
    pid_.track(std::clamp(output, settings.pid.output_low, settings.pid.output_high), set_point, plant_.temperature());
    return output;
}

void Tc10Simulator::update_alarms(double seconds, const StepSettings& settings, double set_point) {
    const Measurement measured = measurement(settings.scale);
    tc10::AlarmInputs inputs;
    inputs.set_point = set_point;
    inputs.standby = settings.state == State::standby;
    inputs.measurement_error = measured.fault != InputFault::none;
    constexpr double infinity = std::numeric_limits<double>::infinity();
    inputs.measured = measured.fault == InputFault::none          ? measured.value
                      : measured.fault == InputFault::under_range ? -infinity
                                                                  : infinity;
    for (std::size_t i = 0; i < alarms_.size(); ++i) alarms_[i].update(seconds, settings.alarms[i], inputs);
}

tc10::AlarmSettings Tc10Simulator::alarm_settings(std::size_t alarm) const {
    const AlarmNames& names = alarm_names[alarm];
    tc10::AlarmSettings settings;
    settings.type = static_cast<tc10::AlarmType>(std::min<std::uint16_t>(value(names.type), 9));
    settings.function = value(names.function);
    settings.low_limit = engineering(names.low);
    settings.high_limit = engineering(names.high);
    settings.threshold = engineering(names.threshold);
    settings.hysteresis = engineering(names.hysteresis);
    settings.delay = signed_raw(value(names.delay));
    settings.enable = value(names.enable);
    return settings;
}

}  // namespace loopwire::device::models
