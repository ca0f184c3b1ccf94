#include "devices/tc10/tc10_simulator.hpp"

#include <array>
#include <chrono>
#include <utility>

namespace loopwire::device::models {
namespace {

constexpr std::uint8_t illegal_data_address = 2;
constexpr std::uint8_t illegal_data_value = 3;
constexpr std::uint8_t device_not_ready = 6;

constexpr std::uint16_t load_defaults_code = 481;  // §5.1 19A

// Words of §5.1 that the manual describes as the same setting as a §5.3 parameter: the set
// points (6A–9A = SP…SP 4, #79–#82), the active set point (5A = A.SP, #83) and the control
// state (15A = oPEr, #130, same codes). Writing either updates both.
constexpr std::array<std::pair<std::string_view, std::string_view>, 6> twins{{
    {"set_point_var", "set_point"},
    {"set_point_2_var", "set_point_2"},
    {"set_point_3_var", "set_point_3"},
    {"set_point_4_var", "set_point_4"},
    {"active_set_point_var", "active_set_point"},
    {"control_state", "operating_mode"},
}};

// Survive word 19 = 481. t.Job (#138) is "Время работы (не сбрасывается)", never reset. The
// serial address and rate (#131, #132) are kept so the master that sent the command can still
// reach the controller; the manual does not say, this is the simulator's choice.
constexpr std::array<std::string_view, 3> kept_by_load_defaults{"work_time", "device_address", "baud_rate"};

// §5.2 13B–16B: output n's remote word is writable only while o<n>F = 0 (nonE).
constexpr std::array<std::pair<std::string_view, std::string_view>, 4> remote_outputs{{
    {"output_1_remote", "output_1_function"},
    {"output_2_remote", "output_2_function"},
    {"output_3_remote", "output_3_function"},
    {"output_4_remote", "output_4_function"},
}};

// The chamber the simulator heats: a small laboratory oven, 400 °C above ambient at full
// power, 5-minute time constant, 10 s from heater to sensor. At --speed 100 it settles from
// cold in a few seconds of real time.
process::ThermalPlantSettings oven() {
    process::ThermalPlantSettings settings;
    settings.ambient = 25.0;
    settings.gain = 400.0;
    settings.time_constant = 300.0;
    settings.dead_time = 10.0;
    settings.lowest_output = -1.0;  // the cooler's share is applied by the process (tc10_process.cpp)
    return settings;
}

}  // namespace

Tc10Simulator::Tc10Simulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment)
    : SimulatedDevice(std::move(profile), std::move(environment)), plant_(oven()) {
    apply_factory_settings();
    describe_line();
    constructed_ = true;
}

// The manual lists no factory values. The simulator's: a PID tuned for the oven above (Pb 20
// units, ti 120 s, td 10 s, tcH 20.0 s; with td 30 s the 10 s dead time makes the loop cycle), output 1 heating, output 2 the alarm-1 relay, set-point
// ramps off (inF), identification word 20 = protocol family 1, parameter table 2 (§5.1 20A:
// high byte family, low byte table version).
void Tc10Simulator::apply_factory_settings() {
    set_value("proportional_band", 20, Persistence::saved);
    set_value("integral_time", 120, Persistence::saved);
    set_value("derivative_time", 10, Persistence::saved);
    set_value("heating_cycle_time", 200, Persistence::saved);
    set_value("output_1_function", 1, Persistence::saved);
    set_value("output_2_function", 3, Persistence::saved);
    set_value("output_2_alarms", 1, Persistence::saved);
    set_value("ramp_up_rate", 9999, Persistence::saved);
    set_value("ramp_down_rate", 9999, Persistence::saved);
    set_value("parameter_table_id", 0x0102);
    apply_code_defaults();
}

// dSPu (#128): the state the controller starts in. 0 = AS.Pr as before power-off (the saved
// control state), 1 = automatic, 2 = oP.0 manual with output 0, 3 = standby. Applied at the
// first request or process step, once the saved contents (--state) are in memory.
void Tc10Simulator::power_on() {
    if (powered_on_) return;
    powered_on_ = true;
    switch (value("power_on_state")) {
        case 1: set_value("control_state", static_cast<std::uint16_t>(State::automatic), Persistence::saved); break;
        case 2:
            set_value("control_state", static_cast<std::uint16_t>(State::manual), Persistence::saved);
            set_value("manual_output_power", 0, Persistence::ram_only);
            break;
        case 3: set_value("control_state", static_cast<std::uint16_t>(State::standby), Persistence::saved); break;
        default: return;
    }
    set_value("operating_mode", value("control_state"), Persistence::saved);
}

// §3.4: exception 6 "неготовность контроллера" is the answer to a well-formed request the
// controller cannot serve in its present situation. The manual names no situation; the
// simulator is not ready while it rewrites its parameters after word 19 = 481.
std::optional<std::optional<Bytes>> Tc10Simulator::intercept(ByteView request_pdu, bool) {
    staged_.clear();
    power_on();
    if (!busy_until_) return std::nullopt;
    if (environment().now() >= *busy_until_) {
        busy_until_.reset();
        return std::nullopt;
    }
    return std::optional<Bytes>(Bytes{static_cast<std::uint8_t>(request_pdu[0] | 0x80), device_not_ready});
}

std::optional<std::uint8_t> Tc10Simulator::accept_write(const Parameter& parameter, std::uint16_t raw,
                                                        const RawValues&) {
    // oPr.E (#129) limits the modes oPEr (#130) offers: 1 = Au.oP auto and manual only,
    // 2 = Au.Sb auto and standby only. A mode outside them is out of range (§4.4 B.2).
    if (parameter.name == "control_state" || parameter.name == "operating_mode") {
        const std::uint16_t enabled = value("operating_modes_enable");
        const auto wanted = static_cast<State>(raw);
        if ((enabled == 1 && wanted == State::standby) || (enabled == 2 && wanted == State::manual)) {
            return illegal_data_value;
        }
    }
    for (const auto& [remote, function] : remote_outputs) {
        // While the controller drives the output the word is not a writable address (§3.4 code 2,
        // as for read-only words).
        if (parameter.name == remote && value(function) != 0) return illegal_data_address;
    }
    return check_rules(parameter, raw);
}

void Tc10Simulator::after_write(const Parameter& parameter, std::uint16_t raw) {
    copy_to_twin(parameter, raw);
    after_line_write(parameter);
    after_rule_write(parameter);
    const std::string_view name = parameter.name;
    if (name == "load_defaults") {
        // Any other value is accepted (no range is printed) and does nothing; the word is a
        // command and reads 0 afterwards.
        if (raw == load_defaults_code) load_defaults();
        set_value("load_defaults", 0, Persistence::saved);
    } else if (name == "alarm_reset" || name == "alarm_acknowledge") {
        // §5.1 13A/14A: writing 1 resets / acknowledges; the word reads 0 again once done.
        // The power failure indicator (§5.1 10A bit 10) goes off with an alarm reset.
        if (name == "alarm_reset" && raw == 1) power_failed_ = false;
        for (std::size_t i = 0; i < alarms_.size() && raw == 1; ++i) {
            if (name == "alarm_reset") alarms_[i].reset();
            if (name == "alarm_acknowledge") alarms_[i].acknowledge(alarm_settings(i).function);
        }
        set_value(name, 0, Persistence::saved);
    } else if (name == "output_power" && state() == State::manual) {
        // §5.1 4A: always writable, effective only in manual mode, where it is the manual
        // output (§5.2 28B, RAM like every word of that area). In automatic or standby the
        // write is answered and has no effect.
        set_value("manual_output_power", raw, Persistence::ram_only);
    }
}

void Tc10Simulator::copy_to_twin(const Parameter& parameter, std::uint16_t raw) {
    for (const auto& [first, second] : twins) {
        if (parameter.name == first) set_value(second, raw, Persistence::saved);
        if (parameter.name == second) set_value(first, raw, Persistence::saved);
    }
}

// §5.1 19A: 481 loads the default parameters. The write itself is answered normally (§4.4 B.1:
// an in-range write gets the standard reply); then the controller is busy (intercept).
// RAM values go back to their defaults too; the oven keeps its temperature.
void Tc10Simulator::load_defaults() {
    std::array<std::uint16_t, kept_by_load_defaults.size()> kept{};
    for (std::size_t i = 0; i < kept.size(); ++i) kept[i] = value(kept_by_load_defaults[i]);
    memory().reset_to_defaults();
    apply_factory_settings();
    for (std::size_t i = 0; i < kept.size(); ++i) set_value(kept_by_load_defaults[i], kept[i], Persistence::saved);
    alarms_ = {};
    ramp_ = {};
    loop_break_ = {};
    pid_ = process::PidController(pid_.settings());
    output_ = 0;
    busy_until_ = environment().now() + std::chrono::duration_cast<SimulationClock::duration>(
                                            std::chrono::duration<double>(defaults_busy_seconds));
}

Tc10Simulator::State Tc10Simulator::state() const {
    const std::uint16_t raw = value("control_state");
    return raw <= 2 ? static_cast<State>(raw) : State::automatic;
}

}  // namespace loopwire::device::models
