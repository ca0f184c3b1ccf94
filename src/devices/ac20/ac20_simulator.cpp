#include "devices/ac20/ac20_simulator.hpp"

#include <algorithm>

namespace loopwire::device::models {
namespace {

// Plant constants (stated so a run at --speed 100 settles a 10-minute process in seconds):
// the furnace holds 925 °C (1700 °F, a usual carburising temperature) with its burners at
// 90 %, and reacts slowly (30 min lag, 30 s transport delay); the AC20 only measures it.
process::ThermalPlantSettings furnace_settings() { return {25.0, 1000.0, 1800.0, 30.0}; }
constexpr double furnace_output = 0.9;
// The atmosphere's carbon potential follows the enrichment gas (natural gas added to the
// endothermic carrier) as a first-order lag with dead time, the dynamics ThermalPlant models:
// 0.30 %C with no enrichment (the carrier gas alone), 1.30 %C at 100 %, 2 min lag, 10 s delay
// (gas transport to the probe).
process::ThermalPlantSettings atmosphere_settings() { return {0.30, 1.00, 120.0, 10.0}; }
constexpr double start_carbon = 0.80;

// Error reply: "If ... a buffer over flows has been received, the slave does not send any
// reply". The manual gives no buffer size, and also says a count over the limits gets error 9
// ("Illegal number of data required"): a buffer just long enough for the 20-word limit would
// turn every over-limit write into silence and leave error 9 to reads only. The receive buffer
// is taken as 64 bytes on the line (a common UART buffer): address, PDU and CRC, so a PDU of
// up to 61 bytes is received (FC16 up to 27 words: over the limit, error 9) and a longer one
// overflows it and gets no reply.
constexpr std::size_t receive_buffer_pdu = 64 - 1 - 2;

}  // namespace

Ac20Simulator::Ac20Simulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment)
    : SimulatedDevice(std::move(profile), std::move(environment)),
      last_activity_(this->environment().now()),
      furnace_(furnace_settings()),
      atmosphere_(atmosphere_settings()) {
    // Factory state: the European table (TB1) and every control group's defaults.
    load_configuration_table(1);
    for (int group : {0, 1, 3, 4, 5, 6, 7, 8}) load_control_defaults(group);
    // Start hot and steady: the furnace at temperature, the atmosphere at its set point.
    const double lag = furnace_settings().dead_time + max_process_step;
    furnace_.set_temperature(furnace_settings().ambient + furnace_settings().gain * furnace_output);
    furnace_.step(lag, furnace_output);
    const double steady_output = (start_carbon - atmosphere_settings().ambient) / atmosphere_settings().gain;
    atmosphere_.set_temperature(start_carbon);
    atmosphere_.step(atmosphere_settings().dead_time + max_process_step, steady_output);
    main_output_ = pid_output_ = steady_output * 100.0;
    restart();
    // Note 5: "At power up, the slave will be in local mode if it was in control mode at
    // power off": a new simulator starts as if switched off in control mode. A --state file
    // may say otherwise (restore_condition, ac20_access.cpp).
    remote_ = false;
    set_value("local_remote", 0);
    refresh_settings();
    measure(0);
    primary_ = primary_value();
    pid_.track(pid_output_, operative_set_point_ / settings_.decimals_scale, primary_);
    update_alarms();
    describe_line();
}

std::vector<std::string> Ac20Simulator::fault_names() const {
    return {"open-probe", "open-thermocouple", "reference-junction", "auto-zero", "air-leak", "heater-failure",
            "error-e130", "error-e140", "dig1-closed", "dig2-closed", "dig3-closed"};
}

void Ac20Simulator::apply_fault(const std::string& name) {
    if (name == "none") {
        faults_.clear();
        device_error_ = 0;
    } else if (name == "error-e130" || name == "error-e140") {
        device_error_ = name == "error-e130" ? 1 : 2;  // word 135: "Control mode with error E.130/E.140"
    } else if (!fault(name)) {
        faults_.push_back(name);
    }
    follow_contacts();  // dig1-closed .. dig3-closed (ac20_contacts.cpp)
}

bool Ac20Simulator::fault(const std::string& name) const {
    return std::find(faults_.begin(), faults_.end(), name) != faults_.end();
}

std::optional<std::optional<Bytes>> Ac20Simulator::intercept(ByteView request_pdu, bool) {
    note_line_activity();
    track_error_condition();
    if (request_pdu.size() > receive_buffer_pdu) return std::make_optional(std::optional<Bytes>{});
    if (auto refusal = error_condition_read_refusal(request_pdu)) return std::make_optional(std::optional<Bytes>(std::move(*refusal)));
    if (auto refusal = menu_read_refusal(request_pdu)) return std::make_optional(std::optional<Bytes>(std::move(*refusal)));
    return std::nullopt;
}

// The checks run from the most general (line and mode, Notes 5-9) to the most specific
// (a procedure's preconditions); the first refusal is the reply's exception code.
std::optional<std::uint8_t> Ac20Simulator::accept_write(const Parameter& parameter, std::uint16_t raw,
                                                        const RawValues&) {
    if (auto refusal = access_refusal(parameter, raw)) return refusal;
    if (auto refusal = error_condition_refusal(parameter)) return refusal;
    if (auto refusal = configuration_refusal(parameter, raw)) return refusal;
    if (auto refusal = load_default_refusal(parameter, raw)) return refusal;
    if (auto refusal = procedure_refusal(parameter, raw)) return refusal;
    return context_refusal(parameter, raw);
}

std::uint16_t Ac20Simulator::on_read(const Parameter& parameter, std::uint16_t stored) {
    // Word 135: an E.130/E.140 error shows in control mode; "The error is reset when read if
    // device is in remote state".
    if (parameter.name == "device_status" && device_error_ != 0 && mode_ == Mode::control &&
        procedure_ == Procedure::none) {
        const int error = device_error_;
        if (remote_) device_error_ = 0;
        return static_cast<std::uint16_t>(error);
    }
    if (auto countdown = countdown_read(parameter)) return *countdown;
    if (auto lock = lock_word_read(parameter, stored)) return *lock;
    if (auto flag = flag_read(parameter, stored)) return *flag;
    if (auto process = process_read(parameter)) return *process;
    return stored;
}

void Ac20Simulator::after_write(const Parameter& parameter, std::uint16_t raw) {
    after_access_write(parameter, raw);
    after_default_write(parameter, raw);
    after_process_write(parameter, raw);
    after_procedure_write(parameter, raw);
    after_alarm_write(parameter, raw);
    after_error_condition_write();
    after_line_write();
    follow_contacts();   // words 2400-2405 may have changed what the contacts select
    refresh_settings();  // a read right after this write already sees the new settings
    update_alarms();
}

void Ac20Simulator::step_process(double seconds) {
    clock_ += seconds;
    if (settings_dirty_) refresh_settings();
    run_timers(seconds);
    follow_contacts();
    measure(seconds);
    control(seconds);
    update_alarms();
}

}  // namespace loopwire::device::models
