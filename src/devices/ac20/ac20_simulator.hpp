#pragma once
// The ac20 behaviour model: what the manual (ENG. 824E rev. 1, English edition; the Korean
// edition where it agrees) says the device does beyond its profile data.
//
//  - Access (ac20_access.cpp): local/remote (Note 5) with the 3 s line-activity fall-back,
//    control / configuration / security code modes (Notes 6-8, word 3051), the software keys
//    (Note 9 and its N.B.: words 347-359, 4000-4011), buffer overflow silence (Error reply).
//  - Configuration (ac20_configuration.cpp): end-of-menu words 3000-3005 with the congruence
//    check (Note 7, errors 101-106), default tables (word 3050, bits 223-232).
//  - Process (ac20_process.cpp): the furnace atmosphere (ac20_atmosphere.hpp) and the carbon
//    controller. Procedures (ac20_procedures.cpp): Smart TUNE, probe test and burn-off (errors
//    50-55, word 135), unsolicited request flags. Alarms (ac20_alarms.cpp): words 113-119,
//    bits 204-206, 222, 233. Contacts (ac20_contacts.cpp): DIG1-DIG3 and the set point they
//    select (words 2400-2405, bits 200-202). Error conditions (ac20_error_condition.cpp):
//    configuration and control mode errors found at start-up (101-106, 151-160), what the
//    device still answers and accepts then, and its 30 s reset.
#include <array>
#include <deque>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "simulation/process/pid_controller.hpp"
#include "simulation/process/thermal_plant.hpp"
#include "simulation/simulated_device.hpp"

namespace loopwire::device::models {

class Ac20Simulator : public SimulatedDevice {
public:
    Ac20Simulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment);

    // Word 121 = software revision × 100 + 43 (manual word 121; the simulated revision is 3).
    static constexpr std::uint16_t identification_code = 3 * 100 + 43;

    std::vector<std::string> fault_names() const override;

protected:
    std::optional<std::optional<Bytes>> intercept(ByteView request_pdu, bool broadcast) override;
    std::optional<std::uint8_t> accept_write(const Parameter& parameter, std::uint16_t raw,
                                             const RawValues& known) override;
    std::uint16_t on_read(const Parameter& parameter, std::uint16_t stored) override;
    void after_write(const Parameter& parameter, std::uint16_t raw) override;
    void step_process(double seconds) override;
    void apply_fault(const std::string& fault) override;
    void describe_line() override;  // ac20_line.cpp
    // ac20_access.cpp: Note 5, power-up after power-off and line activity.
    RawValues condition_at_power_off() const override;
    void restore_condition(const RawValues& condition) override;
    void on_line_activity() override;

private:
    // ac20_line.cpp: words 526-529 written over the line, in effect after the reply.
    void after_line_write();
    void follow_line_words();
    enum class Mode { control, configuration, security };
    enum class Procedure { none, burn_off, purge, probe_test };
    // The areas the error conditions name: configuration, control and security code mode words.
    enum class Area { configuration, control, security, other };

    // What the controller takes from its parameters, re-read after every write.
    struct Settings {
        int primary = 0;              // word 2001: 0 carbon potential, 1 dew point, 2 mV
        bool fahrenheit = false;      // word 2003 4-6
        double decimals_scale = 100;  // 10^(word 300)
        process::PidSettings pid;
        double output_low = 0, output_high = 100;  // words 1003/1004, %
        bool complement = false;                   // word 2205
        double rate_up = -1, rate_down = -1;       // words 1013/1014, raw units per minute; <0 = step
        double carbon_monoxide = 0.20, hydrogen = 0.40;  // words 142/143
        struct Alarm {
            int type = 0, configuration = 0, action = 0;  // words 1100-1111
            bool standby = false;
            double threshold = 0, hysteresis = 0, band_low = 0, band_high = 0;  // raw, words 177-193
        };
        std::array<Alarm, 3> alarms{};
    };
    // One alarm's state (words 113-115, 119, bits 204-206).
    struct AlarmState {
        bool condition = false;     // the process is in the alarm zone (with hysteresis)
        bool latched = false;       // manual-reset alarms remember until bit 222
        bool acknowledged = false;  // acknowledge alarms, by bit 222
        bool standby = false;       // suppressed until the process first leaves the alarm zone
        bool output = false;
        int led = -1, relay = -1;   // last values stored (-1: not yet)
    };

    // ac20_access.cpp
    void note_line_activity();
    void set_remote(bool remote);
    void set_mode(Mode mode);
    std::optional<std::uint8_t> access_refusal(const Parameter& parameter, std::uint16_t raw);
    std::optional<std::uint8_t> mode_entry_refusal(std::uint16_t raw) const;
    std::optional<int> control_group_of(const Parameter& parameter) const;
    bool group_locked(int group) const;
    std::optional<std::uint16_t> lock_word_read(const Parameter& parameter, std::uint16_t stored) const;
    void after_access_write(const Parameter& parameter, std::uint16_t raw);
    void restart();

    // ac20_configuration.cpp
    static std::optional<int> configuration_menu_of(const Parameter& parameter);
    std::optional<std::uint8_t> configuration_refusal(const Parameter& parameter, std::uint16_t raw);
    bool menu_congruent(int menu) const;
    std::vector<const Parameter*> parameters_read_by(ByteView request_pdu);
    std::optional<Bytes> menu_read_refusal(ByteView request_pdu);
    void load_configuration_table(int table);
    void load_control_defaults(int group);
    std::optional<std::uint8_t> load_default_refusal(const Parameter& parameter, std::uint16_t raw) const;
    void after_default_write(const Parameter& parameter, std::uint16_t raw);
    void store_default(std::string_view name, int raw);

    // ac20_error_condition.cpp
    Area area_of(const Parameter& parameter) const;
    std::optional<std::uint8_t> start_up_error() const;
    void track_error_condition();
    bool is_configuration_error() const;
    std::optional<Bytes> error_condition_read_refusal(ByteView request_pdu);
    std::optional<std::uint8_t> error_condition_refusal(const Parameter& parameter) const;
    void after_error_condition_write();

    // ac20_process.cpp, ac20_procedures.cpp
    std::optional<std::uint8_t> procedure_refusal(const Parameter& parameter, std::uint16_t raw) const;
    std::optional<std::uint8_t> context_refusal(const Parameter& parameter, std::uint16_t raw) const;
    void after_process_write(const Parameter& parameter, std::uint16_t raw);
    void after_procedure_write(const Parameter& parameter, std::uint16_t raw);
    std::optional<std::uint16_t> process_read(const Parameter& parameter) const;
    std::optional<std::uint16_t> flag_read(const Parameter& parameter, std::uint16_t stored);
    void refresh_settings();
    void measure(double seconds);
    void control(double seconds);
    void run_timers(double seconds);
    void run_intervals();
    void schedule_interval(bool probe_test);
    std::optional<std::uint16_t> countdown_read(const Parameter& parameter) const;
    std::optional<std::uint8_t> procedure_refusal_for(bool probe_test) const;
    void start_procedure(bool probe_test);
    void finish_procedure();
    void raise_change_flag(const std::string& flag);
    double primary_value() const;
    double probe_drift_per_minute() const;
    std::uint16_t temperature_word(double celsius) const;
    bool fault(const std::string& name) const;
    bool measurement_fault() const;

    // ac20_contacts.cpp
    bool contact_level(std::size_t index) const;
    int selected_set_point() const;
    std::uint16_t set_point_word(int type) const;
    void follow_contacts();

    // ac20_alarms.cpp
    void read_alarm_settings(Settings& settings) const;
    void update_alarms();
    void after_alarm_write(const Parameter& parameter, std::uint16_t raw);

    // Line and modes.
    bool remote_ = false;
    SimulationClock::time_point last_activity_;
    Mode mode_ = Mode::control;
    bool control_unlocked_ = false;  // word 349 was written with the control combination
    std::optional<int> open_menu_;   // configuration menu being programmed (Note 7)
    bool start_up_check_due_ = false;                // a (re)start: check at the next request
    std::optional<std::uint8_t> error_condition_;    // 101-106 or 151-160 while shown
    SimulationClock::time_point error_since_;        // the 30 s reset counts from here

    // Process.
    double clock_ = 0;  // process seconds since power-on (the base's process_time() lags a request)
    Settings settings_;
    bool settings_dirty_ = true;
    process::ThermalPlant furnace_;
    process::ThermalPlant atmosphere_;  // carbon potential (%C) as a lag on the enrichment gas
    process::PidController pid_;
    double pid_output_ = 0;             // %
    double main_output_ = 0;            // %, after limits and conditioning
    bool manual_ = false;
    double operative_set_point_ = 0;    // raw units of the primary variable
    int operative_set_point_type_ = 1;  // word 136
    int last_selection_ = 1;            // the set point the contacts selected last (1-4)
    double millivolts_ = 0;             // what the probe input reads
    double temperature_ = 0;            // °C, what the thermocouple input reads
    std::deque<std::pair<double, double>> millivolt_history_;  // (process time, mV), last minute
    std::vector<std::string> faults_;
    double primary_ = 0;                // last primary variable, engineering units
    std::array<AlarmState, 3> alarms_{};
    bool arm_standby_ = true;           // standby alarms re-arm at (re)start

    // Smart and procedures.
    double tune_left_ = 0;              // s of the Smart TUNE phase still to run
    Procedure procedure_ = Procedure::none;
    double procedure_left_ = 0;         // s
    double quiet_since_ = 0;            // process time of power-on or of the last procedure's end
    std::optional<double> next_burn_off_, next_probe_test_;  // process time an automatic one is due
    int device_error_ = 0;              // word 135: 1 = E.130, 2 = E.140, until read in remote
};

}  // namespace loopwire::device::models
