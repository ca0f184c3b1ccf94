// What the TC10's computed words answer (§5.1, §5.2): the measurement, set point, output,
// alarm, output and instrument status words follow the process, whatever was stored.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "devices/tc10/tc10_simulator.hpp"

namespace loopwire::device::models {
namespace {

// §5.1 1A: what word 1 sends instead of a measurement.
constexpr std::uint16_t out_of_range_code = 10000;  // under-range and over-range alike
constexpr std::uint16_t adc_overflow_code = 10001;

std::uint16_t word_of(double counts) {
    return static_cast<std::uint16_t>(static_cast<std::int16_t>(std::lround(counts)));
}

std::uint16_t bit(bool on, unsigned position) { return static_cast<std::uint16_t>(on ? 1U << position : 0U); }

// §5.1 11A prints output 1 at bit 0, output 2 at bit 1, output 3 at bit 3, output 4 at bit 4
// (bit 2 skipped); the profile keeps the bits as printed.
constexpr std::array<unsigned, 4> output_bits{0, 1, 3, 4};

// o<n>F codes (§5.3.2 #14) the simulator drives.
constexpr std::uint16_t function_heating = 1;   // H.rEG
constexpr std::uint16_t function_cooling = 2;   // c.rEG
constexpr std::uint16_t function_alarm = 3;     // AL
constexpr std::uint16_t function_burnout = 12;  // or.bo
constexpr std::uint16_t function_power_failure = 13;  // P.FAL
constexpr std::uint16_t function_burnout_or_power = 14;  // bo.PF
constexpr std::uint16_t function_standby = 15;  // St.bY
constexpr std::uint16_t function_always_on = 18;  // on

constexpr std::array<std::string_view, 4> functions{"output_1_function", "output_2_function", "output_3_function",
                                                   "output_4_function"};

// Time-proportioning: a relay output is on for `percent` of each cycle.
bool cycle_on(double percent, double cycle_seconds, double time) {
    if (percent <= 0) return false;
    if (percent >= 100 || cycle_seconds <= 0) return true;
    return std::fmod(time, cycle_seconds) < cycle_seconds * percent / 100.0;
}

}  // namespace

std::uint16_t Tc10Simulator::on_read(const Parameter& parameter, std::uint16_t stored) {
    return computed_word(parameter.name).value_or(stored);
}

std::optional<std::uint16_t> Tc10Simulator::computed_word(std::string_view name) const {
    if (name == "measured_value" || name == "measured_value_b") return measured_raw();
    if (name == "measured_value_decimals" || name == "measured_value_decimals_b") return value("decimal_point");
    if (name == "operating_set_point" || name == "operating_set_point_b") return word_of(working_set_point() * scale());
    // Output power in hundredths of a percent (§5.1 4A, §5.2 3B–5B).
    if (name == "output_power" || name == "output_power_b") return word_of(output_ * 100);
    if (name == "heating_output_power") return word_of(std::max(0.0, output_) * 100);
    if (name == "cooling_output_power") return word_of(std::max(0.0, -output_) * 100);
    if (name == "alarm_status") return alarm_status();
    if (name == "alarm_1_state") return alarms_[0].active() ? 1 : 0;
    if (name == "alarm_2_state") return alarms_[1].active() ? 1 : 0;
    if (name == "alarm_3_state") return alarms_[2].active() ? 1 : 0;
    if (name == "loop_break_alarm_state") return loop_break_.active() ? 1 : 0;  // §5.2 10B
    if (name == "overload_alarm_state") return overload() ? 1 : 0;             // §5.2 11B
    if (name == "output_status") return output_status();
    if (name == "instrument_status") return instrument_status();
    if (name == "controller_state") return controller_state();
    return std::nullopt;
}

std::uint16_t Tc10Simulator::measured_raw() const {
    const Measurement measured = measurement();
    switch (measured.fault) {
        case InputFault::none: return word_of(measured.value * scale());
        case InputFault::adc_overflow: return adc_overflow_code;
        case InputFault::over_range:
        case InputFault::under_range: return out_of_range_code;
    }
    return out_of_range_code;
}

// §5.1 10A: bits 0–2 alarms 1–3; bit 9 loop break alarm (§5.3.6); bit 10 power failure
// indicator (tc10_line.cpp); bit 11 general error, set while the measurement is in error;
// bit 12 overload alarm.
std::uint16_t Tc10Simulator::alarm_status() const {
    std::uint16_t word = 0;
    for (unsigned i = 0; i < alarms_.size(); ++i) word |= bit(alarms_[i].active(), i);
    return word | bit(loop_break_.active(), 9) | bit(power_failed_, 10) |
           bit(measurement().fault != InputFault::none, 11) | bit(overload(), 12);
}

// §5.2 11B "Состояние сигнализации перегрузки" (overload alarm state) and §5.3.2 #17 "+32 =
// Перегрузка на выходе 4" (overload on output 4): only output 4 is watched, so there is an
// overload only while IO4.F (#9) makes I/O 4 an output: 0 = on (transmitter supply) or 1 = out4;
// as a digital input (2, 3) nothing can be overloaded.
bool Tc10Simulator::overload() const { return overloaded_ && value("io4_function") <= 1; }

std::uint16_t Tc10Simulator::output_status() const {
    std::uint16_t word = 0;
    for (int output = 1; output <= 4; ++output) word |= bit(output_on(output), output_bits[static_cast<std::size_t>(output - 1)]);
    return word;
}

// What physical output n does under its function o<n>F (§5.3.2 #14) and action o<n>Ac (#18:
// 0 = dir "Прямое действие", direct; 1 = rEU "Обратное действие", reverse; 2, 3 the same with
// the LED reversed). Reverse action inverts the output: a relay that is off while its function
// is on. An output the controller does not use (nonE) is driven over the serial line, and
// §5.1 11A says its bit then stays 0, whatever its action.
bool Tc10Simulator::output_on(int output) const {
    static constexpr std::array<std::string_view, 4> actions{"output_1_action", "output_2_action",
                                                             "output_3_action", "output_4_action"};
    const auto index = static_cast<std::size_t>(output - 1);
    if (value(functions[index]) == 0) return false;
    const std::uint16_t action = value(actions[index]);
    const bool reverse = action == 1 || action == 3;
    return function_on(output) != reverse;
}

// Output n's function o<n>F (§5.3.2 #14) and alarm mask o<n>AL (#17: +1/+2/+4 alarms 1–3,
// +8 loop break alarm, +16 sensor fault, +32 output 4 overload).
bool Tc10Simulator::function_on(int output) const {
    static constexpr std::array<std::string_view, 4> masks{"output_1_alarms", "output_2_alarms", "output_3_alarms",
                                                           "output_4_alarms"};
    const bool error = measurement().fault != InputFault::none;
    const std::uint16_t mask = value(masks[static_cast<std::size_t>(output - 1)]);
    switch (value(functions[static_cast<std::size_t>(output - 1)])) {
        case function_heating: return cycle_on(output_, value("heating_cycle_time") / 10.0, process_time());
        case function_cooling: return cycle_on(-output_, value("cooling_cycle_time") / 10.0, process_time());
        case function_alarm: {
            bool on = ((mask & 8) != 0 && loop_break_.active()) || ((mask & 16) != 0 && error) ||
                      ((mask & 32) != 0 && overload());
            for (unsigned i = 0; i < alarms_.size(); ++i) on = on || (((mask >> i) & 1U) != 0 && alarms_[i].active());
            return on;
        }
        case function_burnout: return error;
        case function_power_failure: return power_failed_;
        case function_burnout_or_power: return error || power_failed_;
        case function_standby: return state() == State::standby;
        case function_always_on: return true;
        default: return false;
    }
}

// §5.1 12A: bit 0 auto, 1 manual, 2 standby, 3 remote set point in use, 9 set-point ramp
// running, 12 measurement error.
std::uint16_t Tc10Simulator::instrument_status() const {
    const State now = state();
    return bit(now == State::automatic, 0) | bit(now == State::manual, 1) | bit(now == State::standby, 2) |
           bit(remote_set_point_in_use(), 3) | bit(ramp_running(), 9) |
           bit(measurement().fault != InputFault::none, 12);
}

// §5.2 12B uses its own codes: 0 standby, 1 automatic, 2 tuning (not simulated), 3 manual.
std::uint16_t Tc10Simulator::controller_state() const {
    switch (state()) {
        case State::standby: return 0;
        case State::manual: return 3;
        case State::automatic: break;
    }
    return 1;
}

}  // namespace loopwire::device::models
