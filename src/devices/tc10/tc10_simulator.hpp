#pragma once
// The Yokogawa TC10 behaviour model (tc10-modbus-im05c01e81-03.ru.txt): control states,
// alarms, load defaults, the busy answer and the heated process, beyond its profile data.
// The class is split by concern: tc10_simulator.cpp (writes, modes, defaults, busy),
// tc10_readings.cpp (what the computed words answer), tc10_process.cpp (plant, PID, alarms,
// faults), tc10_write_rules.cpp (rules that tie words together).
#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "devices/tc10/tc10_alarms.hpp"
#include "devices/tc10/tc10_loop_break.hpp"
#include "devices/tc10/tc10_ramp.hpp"
#include "simulation/process/pid_controller.hpp"
#include "simulation/process/thermal_plant.hpp"
#include "simulation/simulated_device.hpp"

namespace loopwire::device::models {

class Tc10Simulator : public SimulatedDevice {
public:
    Tc10Simulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment);

    // After word 19 = 481 the controller answers exception 6 for this long (protocol time).
    static constexpr double defaults_busy_seconds = 1.0;

protected:
    std::optional<std::optional<Bytes>> intercept(ByteView request_pdu, bool broadcast) override;
    std::optional<std::uint8_t> accept_write(const Parameter& parameter, std::uint16_t raw,
                                             const RawValues& known) override;
    std::uint16_t on_read(const Parameter& parameter, std::uint16_t stored) override;
    void after_write(const Parameter& parameter, std::uint16_t raw) override;
    void step_process(double seconds) override;
    std::vector<std::string> fault_names() const override;
    void apply_fault(const std::string& fault) override;
    void describe_line() override;  // tc10_line.cpp

private:
    // tc10_line.cpp: Add and bAud written over the line, in effect after the reply.
    void after_line_write(const Parameter& parameter);
    void follow_line_words();
    // Control state, word 15 / oPEr 768 (§5.1 15A, §5.3.10 #130).
    enum class State : std::uint16_t { automatic = 0, manual = 1, standby = 2 };
    // Measurement errors and what word 1 answers for them (§5.1 1A).
    enum class InputFault { none, over_range, under_range, adc_overflow };
    // The measurement as the controller sees it: the plant temperature rounded to display
    // counts, or the error that replaces it.
    struct Measurement {
        InputFault fault = InputFault::none;
        double value = 0;  // engineering units; meaningless while fault != none
    };

    // Everything one process step reads from memory. Settings cannot change while the base
    // class walks one catch-up in steps (no request is served in between), so they are read
    // once per catch-up: process_time() moves only when a catch-up ends.
    struct StepSettings {
        State state = State::automatic;
        double scale = 1;
        double final_set_point = 0;  // before the ramp (§5.3.10 #122 diSP 2 = SPF)
        tc10::RampRates ramp;
        double manual_output = 0;  // %
        double error_output = 0;   // %
        std::uint16_t error_mode = 0;
        process::PidSettings pid;
        std::array<tc10::AlarmSettings, 3> alarms{};
        tc10::LoopBreakSettings loop_break;
    };

    // tc10_simulator.cpp
    void apply_factory_settings();
    void power_on();
    void load_defaults();
    void copy_to_twin(const Parameter& parameter, std::uint16_t raw);
    State state() const;

    // tc10_write_rules.cpp: dP per input type, quick-configuration codes 22–25, limits named by
    // other parameters (§5.1 22A–25A, §5.3.1 #2, §5.3).
    void apply_code_defaults();
    std::uint16_t current(std::string_view name) const;  // as staged in this request, else memory
    std::optional<std::uint8_t> check_rules(const Parameter& parameter, std::uint16_t raw);
    void after_rule_write(const Parameter& parameter);
    void limit_decimal_point();
    void apply_quick_configuration();
    void follow_limits(const Parameter& limit);

    // tc10_readings.cpp
    std::optional<std::uint16_t> computed_word(std::string_view name) const;
    std::uint16_t measured_raw() const;
    std::uint16_t alarm_status() const;
    std::uint16_t output_status() const;
    std::uint16_t instrument_status() const;
    std::uint16_t controller_state() const;
    bool output_on(int output) const;
    bool function_on(int output) const;
    bool overload() const;

    // tc10_process.cpp
    double scale() const;  // 10^dP: engineering units per raw count
    double engineering(std::string_view name) const;
    double final_set_point() const;
    double working_set_point() const;
    tc10::RampRates ramp_rates() const;
    bool ramp_running() const;
    double step_ramp(double seconds, const StepSettings& settings);
    bool remote_set_point_in_use() const;
    Measurement measurement() const { return measurement(scale()); }
    Measurement measurement(double scale) const;
    const StepSettings& step_settings();
    process::PidSettings pid_settings() const;
    tc10::AlarmSettings alarm_settings(std::size_t alarm) const;
    tc10::LoopBreakSettings loop_break_settings() const;
    double next_output(double seconds, const StepSettings& settings, double set_point);
    void update_alarms(double seconds, const StepSettings& settings, double set_point);

    process::ThermalPlant plant_;
    process::PidController pid_;
    std::array<tc10::Alarm, 3> alarms_{};
    tc10::SetPointRamp ramp_;
    tc10::LoopBreakAlarm loop_break_;
    InputFault fault_ = InputFault::none;
    bool loop_open_ = false;      // fault "loop-break": the output no longer reaches the oven
    bool overloaded_ = false;     // fault "output-4-overload"
    bool power_failed_ = false;   // §5.1 10A bit 10, set by a restart from saved contents
    bool constructed_ = false;    // describe_line() from now on means a reload (load_saved)
    double output_ = 0;  // % -100…100, what the controller drives now
    std::optional<SimulationClock::time_point> busy_until_;
    bool powered_on_ = false;  // dSPu applied (after --state has been loaded)
    StepSettings step_settings_;
    std::optional<double> step_settings_time_;  // process_time() they were read at
    std::map<std::string, std::uint16_t, std::less<>> staged_;  // accepted so far in this request
};

}  // namespace loopwire::device::models
