#include "devices/rampsoak/rampsoak_simulator.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <random>

#include <fmt/format.h>

#include "devices/rampsoak/rampsoak_alarms.hpp"

namespace loopwire::device::models {
namespace {

// The chamber the simulated controller heats: a small electric kiln that would reach 825 °C
// at full power (800 °C above a 25 °C room), with a 4-minute time constant and an 8 s lag
// between heater and thermocouple. Ten minutes of process pass in 6 s of real time at --speed
// 100, and a set-point step settles (with the factory PID terms below) in about 150 s.
constexpr process::ThermalPlantSettings kiln{25.0, 800.0, 240.0, 8.0};

// OBIT (§7, 0088H): the bits this model drives.
constexpr std::uint16_t out1_led = 1u << 0;
constexpr std::uint16_t alarm_1_led = 1u << 3;  // AL2 and AL3 follow at bits 4 and 5
constexpr std::uint16_t program_led = 1u << 6;
constexpr std::uint16_t input_1_error = 1u << 8;  // message IN1E

// §7 PV row: the PV word spans -1999~9999 display counts.
constexpr double pv_lowest = -1999;
constexpr double pv_highest = 9999;

// Measurement noise on the shown PV (standard deviation, °C); the control itself uses the
// filtered measurement, as the PV filter (PVFT) would give it.
constexpr double pv_noise = 0.03;

std::uint16_t word_of(long value) {
    return static_cast<std::uint16_t>(static_cast<std::int16_t>(std::clamp<long>(value, -32768, 32767)));
}

}  // namespace

RampSoakSimulator::RampSoakSimulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment)
    : SimulatedDevice(std::move(profile), std::move(environment)), plant_(kiln) {
    find_cells();
    set_factory_values();
    describe_line();
    pid_.set_settings(pid_settings());
    publish();
}

void RampSoakSimulator::find_cells() {
    const auto cell = [this](const std::string& name) {
        MemoryCell* found = memory().cell(name);
        assert(found != nullptr && "the rampsoak profile lacks a parameter the model drives");
        return found;
    };
    set_value_ = cell("set_value");
    output_limit_ = cell("output_limit");
    program_pattern_ = cell("program_pattern");
    program_segment_ = cell("program_segment");
    program_countdown_ = cell("program_countdown");
    for (std::size_t p = 0; p < patterns_.size(); ++p) {
        for (std::size_t s = 0; s < segments_per_pattern; ++s) {
            const std::string prefix = fmt::format("pattern_{}_segment_{}_", p + 1, s + 1);
            patterns_[p][s] = {cell(prefix + "set_point"), cell(prefix + "run_time"), cell(prefix + "output_limit")};
        }
    }
    proportional_band_ = cell("out1_proportional_band");
    integral_time_ = cell("out1_integral_time");
    derivative_time_ = cell("out1_derivative_time");
    hysteresis_ = cell("out1_hysteresis");
    decimal_point_ = cell("decimal_point");
    lower_set_point_limit_ = cell("lower_set_point_limit");
    upper_set_point_limit_ = cell("upper_set_point_limit");
    pv_compensation_ = cell("pv_compensation");
    unit_ = cell("unit");
    for (std::size_t i = 0; i < 3; ++i) {
        alarm_sets_[i] = cell(fmt::format("alarm_{}_set", i + 1));
        alarm_modes_[i] = cell(fmt::format("alarm_{}_mode", i + 1));
    }
    output_percentage_ = cell("output_percentage");
    status_ = cell("controller_status");
    process_value_ = cell("process_value");
}

// What the controller holds when it leaves the factory. §1 gives the Level-3 defaults (ID
// number 1, baud 384 = 38400, bits OB1); the rest is the model's choice, since the manual
// prints no defaults: DP = 1 as in every example (§4.7.1 PV 03E8H = 100.0), full output
// (OUTL and every segment's OUTn 100.0 %), and PID terms tuned for the kiln above: a 125 °C
// step settles within 1 °C in about 150 s, without overshoot.
void RampSoakSimulator::set_factory_values() {
    set_value("id_number", 1);
    set_value("baud_rate", 4);
    set_value("communication_bits", 0);
    set_value("decimal_point", 1, Persistence::saved);
    // LSPL/USPL: the whole PV display span (§7 PV row, -1999~9999 counts), so out of the box no
    // set point the display can show is refused.
    set_value("lower_set_point_limit", word_of(static_cast<long>(pv_lowest)), Persistence::saved);
    set_value("upper_set_point_limit", word_of(static_cast<long>(pv_highest)), Persistence::saved);
    set_value("output_limit", 1000, Persistence::saved);
    for (const PatternCells& cells : patterns_) {
        for (const SegmentCells& segment : cells) memory().store(*segment.output_limit, 1000, Persistence::saved);
    }
    set_value("out1_proportional_band", 400, Persistence::saved);  // 40.0 °C
    set_value("out1_integral_time", 240, Persistence::saved);      // s
    set_value("out1_derivative_time", 10, Persistence::saved);     // s
    set_value("out1_hysteresis", 5, Persistence::saved);           // 0.5 °C, on/off (P1 = 0) only
}

// §1 Level 3: PSL selects PU (MODBUS RTU, default), PACI (MODBUS ASCII) or PRE (Linking), and
// only from the front panel (§7: PSL is 03H only). A device that answers on a link must be set
// to that link's protocol, so PSL starts as the framing it is served with; on a link the
// device does not speak (Modbus/TCP) it keeps the §1 default, RTU.
// §6.2: Linking M (served as FC6) modifies RAM only, "not maintained after power off"; W
// (served as FC16 with one register) writes RAM and EEPROM. §4/§5 say nothing of where a
// Modbus FC06/FC10 write goes; the model saves it (the profile's registers are settings kept
// in EEPROM, and a Modbus master has no other way to make a setting last).
Persistence RampSoakSimulator::persistence_of(std::uint8_t function) const {
    return environment().framing == "linking" && function == 0x06 ? Persistence::ram_only : Persistence::saved;
}

double RampSoakSimulator::scale() const { return std::pow(10.0, std::min<int>(decimal_point_->raw, 3)); }

// DP-scaled words (§7 DP row, 004BH): engineering = raw / 10^DP.
double RampSoakSimulator::engineering(const MemoryCell* cell) const {
    return static_cast<std::int16_t>(cell->raw) / scale();
}

std::uint16_t RampSoakSimulator::display_raw(double engineering) const {
    return word_of(std::lround(engineering * scale()));
}

ProgramPattern RampSoakSimulator::pattern() const {
    ProgramPattern pattern{};
    const std::uint16_t selected = program_pattern_->raw;
    if (selected < 1 || selected > patterns_.size()) return pattern;
    const PatternCells& cells = patterns_[selected - 1];
    for (std::size_t s = 0; s < segments_per_pattern; ++s) {
        pattern[s].set_point = engineering(cells[s].set_point);
        pattern[s].run_time = cells[s].run_time->raw * 60.0;  // TM_n in minutes (rampsoak_program.hpp)
        pattern[s].output_limit = cells[s].output_limit->raw / 10.0;
    }
    return pattern;
}

// The working set point: the program's while one is active, else SV (§7, 0000H).
double RampSoakSimulator::set_point() const {
    return program_.working_set_point(pattern()).value_or(engineering(set_value_));
}

// OUTL (§7, 0001H, 0~1000 = 0.0~100.0 %) always limits the output; a running segment's OUTn
// limits it further (the lower of the two applies).
double RampSoakSimulator::output_limit() const {
    const double limit = output_limit_->raw / 10.0;
    return std::min(limit, program_.output_limit(pattern()).value_or(limit));
}

// §7 UNIT (0066H) "Unit of PV and SV", "0000H=C 0001H=F 0002H=A": the PV and SV words, and
// every word compared with them (SV_n, AL1-AL3, LSPL/USPL, PVOS, P1, HYS1), are in that unit.
// The chamber is modelled in °C; with F the PV reads in °F and the controller works in °F.
// Choices (the manual says no more): a change of UNIT does not convert the stored set points
// (SV 100.0 means 100.0 °F after the switch to F, as a number typed on the panel would), and A
// (a linear input scaled by ANL1/ANH1, not modelled) shows the same numbers as C.
double RampSoakSimulator::in_configured_unit(double celsius) const {
    return unit_->raw == 1 ? celsius * 9.0 / 5.0 + 32.0 : celsius;
}

// What the controller measures and controls: the chamber temperature in the configured unit
// plus PVOS (§7, 0065H, "PV Compensation"), an offset in PV units (DP-scaled) added to the
// measurement. The controller acts on the compensated PV, the value it shows.
double RampSoakSimulator::measured_value() const {
    return in_configured_unit(plant_.temperature()) + engineering(pv_compensation_);
}

// P1 (§7, 0039H, 0~2000) is taken in PV display counts like HYS1, so with DP = 1 P1 = 400 is a
// 40.0 °C band (span 100 makes the PID's "% of span" the band in the PV's unit); P1 = 0 is
// on/off control with HYS1. I1 (0~3600) and D1 (0~900) are seconds.
process::PidSettings RampSoakSimulator::pid_settings() const {
    process::PidSettings settings;
    settings.span = 100.0;
    settings.proportional_band = engineering(proportional_band_);
    settings.integral_time = integral_time_->raw;
    settings.derivative_time = derivative_time_->raw;
    settings.hysteresis = engineering(hysteresis_);
    settings.output_low = 0.0;
    settings.output_high = output_limit();
    return settings;
}

void RampSoakSimulator::step_process(double seconds) {
    program_.step(seconds, pattern());
    pid_.set_settings(pid_settings());
    // A broken sensor gives the controller nothing to act on: the output goes to 0 % (the safe
    // state for a heater) until the input is restored.
    output_ = input_open_ ? 0.0 : pid_.step(seconds, set_point(), measured_value());
    if (input_open_) pid_.track(0.0, set_point(), measured_value());
    plant_.step(seconds, output_ / 100.0);
    publish();
}

// Open input (sensor break): OBIT shows message IN1E (§7, 0088H bit 8). The manual gives no PV
// word for it; the model reads the top of the printed PV range, 9999 counts, as a burnt-out
// thermocouple drives a controller upscale.
double RampSoakSimulator::shown_process_value() {
    if (input_open_) return pv_highest / scale();
    std::normal_distribution<double> noise(0.0, pv_noise);
    return std::clamp(measured_value() + noise(random()), pv_lowest / scale(), pv_highest / scale());
}

// OBIT (§7, 0088H): OUT1 LED while the heating output is on, AL1-AL3 LEDs per alarm, PRO LED
// while a program runs, IN1E on an open input. OUT2 (no cooling output modelled), AT (auto
// tuning is not modelled), MAN (the map has no manual mode) and the other messages stay off.
std::uint16_t RampSoakSimulator::status_word(double process_value) const {
    std::uint16_t status = 0;
    if (output_ > 0) status |= out1_led;
    const AlarmInputs inputs{process_value, set_point(), program_.segment_number()};
    for (std::size_t i = 0; i < 3; ++i) {
        const auto raw = static_cast<std::int16_t>(alarm_sets_[i]->raw);
        if (alarm_on(alarm_modes_[i]->raw, engineering(alarm_sets_[i]), raw, inputs)) {
            status |= static_cast<std::uint16_t>(alarm_1_led << i);
        }
    }
    if (program_.running()) status |= program_led;
    if (input_open_) status |= input_1_error;
    return status;
}

// The read-only words the process drives (§7: SEG, TIMR, OUT%, OBIT, PV); RAM only.
void RampSoakSimulator::publish() {
    const double process_value = shown_process_value();
    memory().store(*process_value_, display_raw(process_value), Persistence::ram_only);
    memory().store(*output_percentage_, static_cast<std::uint16_t>(std::lround(output_ * 10.0)), Persistence::ram_only);
    memory().store(*program_segment_, program_.segment_number(), Persistence::ram_only);
    memory().store(*program_countdown_, program_.remaining_minutes(pattern()), Persistence::ram_only);
    memory().store(*status_, status_word(process_value), Persistence::ram_only);
}

// While a program is active SV (0000H) reads the working set point, as the controller's SV
// display shows it; the stored SV stays the fixed set point used when PTN goes back to 0.
std::uint16_t RampSoakSimulator::on_read(const Parameter& parameter, std::uint16_t stored) {
    if (&parameter != set_value_->parameter) return stored;
    const auto working = program_.working_set_point(pattern());
    return working ? display_raw(*working) : stored;
}

// PTN (§7, 0006H, 0~2): writing 1 or 2 starts that pattern from segment 1 (again, if it was
// running), writing 0 stops the program. The map has no other program control: no run, hold
// or reset register, so hold is out of reach over the line. Nor does any register switch the
// controller to manual: OUT% (0087H) is read-only (03H) and no A/M word is listed, so the
// output is always the controller's and OBIT's MAN LED (bit 7) stays off. A restart (power on)
// leaves the program stopped whatever PTN holds.
void RampSoakSimulator::after_write(const Parameter& parameter, std::uint16_t raw) {
    if (&parameter == program_pattern_->parameter) {
        if (raw == 0) {
            program_.stop();
        } else {
            program_.start(measured_value());
        }
    }
    publish();
}

void RampSoakSimulator::apply_fault(const std::string& fault) {
    input_open_ = fault == "open-input";
    publish();
}

}  // namespace loopwire::device::models
