// Procedures (probe test, burn-off and purge), Smart TUNE, and the unsolicited request flags.
#include <algorithm>
#include <cmath>
#include <random>

#include "devices/ac20/ac20_simulator.hpp"
#include "devices/ac20/ac20_words.hpp"

namespace loopwire::device::models {
namespace {

// Error reply, codes 50-55 (start of a probe test or a burn-off).
constexpr std::uint8_t another_procedure = 50;
constexpr std::uint8_t tune_in_progress = 51;
constexpr std::uint8_t too_soon = 52;
constexpr std::uint8_t probe_too_cold = 53;
constexpr std::uint8_t probe_output_low = 54;
constexpr std::uint8_t probe_unstable = 55;
constexpr double quiet_period = 5 * 60.0;        // 52: "5 minutes from power on or from end of another procedure"
constexpr double minimum_probe_celsius = 538.0;  // 53: "less than 1000°F/538°" (Korean: "538 or below"; English kept)
constexpr double minimum_probe_mv = 1000.0;      // 54: "less than 1000 mV"
constexpr double maximum_drift = 10.0;           // 55: "drift > 10 mV/minute" (Korean: "10 mV or more"; English kept)

// Not in the manual (it refers to the AC20's technical specification): the probe test
// lasts one minute; the Smart TUNE phase five minutes, after which adaptive control goes on.
constexpr double probe_test_seconds = 60.0;
constexpr double tune_seconds = 5 * 60.0;
constexpr double probe_resistance_kohm = 4.8;
constexpr double probe_response_seconds = 12.5;

}  // namespace

void Ac20Simulator::run_timers(double seconds) {
    if (tune_left_ > 0) {
        tune_left_ -= seconds;
        if (tune_left_ <= 0) {
            // TUNE done, adaptive control goes on: a group 2 status change the device made
            // itself, so flagged (bit 252: "The information of group 2 are on bits 211, 212, 221").
            set_value("tune_status", 0);
            raise_change_flag("change_flag_group_2");
        }
    }
    run_intervals();
    if (procedure_ == Procedure::none) return;
    procedure_left_ -= seconds;
    if (procedure_left_ <= 0) finish_procedure();
}

// Words 1302/1303: automatic burn-off and probe test every so many minutes (7FFFh = none),
// counted from when the interval was set or the device started; 1304/1305 count down in
// minutes. A procedure due while the device refuses it (errors 50-55) starts as soon as it may.
void Ac20Simulator::run_intervals() {
    for (const bool probe_test : {false, true}) {
        auto& due = probe_test ? next_probe_test_ : next_burn_off_;
        if (!due || clock_ < *due || procedure_refusal_for(probe_test)) continue;
        start_procedure(probe_test);
        schedule_interval(probe_test);
    }
}

void Ac20Simulator::schedule_interval(bool probe_test) {
    const std::uint16_t minutes = value(probe_test ? "probe_test_interval" : "burn_off_interval");
    auto& due = probe_test ? next_probe_test_ : next_burn_off_;
    due = minutes == 0x7FFF || signed_word(minutes) <= 0 ? std::nullopt
                                                        : std::optional<double>(clock_ + signed_word(minutes) * 60.0);
}

std::optional<std::uint16_t> Ac20Simulator::countdown_read(const Parameter& parameter) const {
    if (parameter.table != Table::holding_registers || (parameter.address != 1304 && parameter.address != 1305)) {
        return std::nullopt;
    }
    const auto& due = parameter.address == 1305 ? next_probe_test_ : next_burn_off_;
    if (!due) return 0x7FFF;
    return word_of(std::ceil(std::max(0.0, *due - clock_) / 60.0));
}

void Ac20Simulator::finish_procedure() {
    if (procedure_ == Procedure::burn_off) {  // word 135: 3 burn-off, then 4 purge
        procedure_ = Procedure::purge;
        procedure_left_ = std::max(0.0, signed_word(value("purge_timer")));
        return;
    }
    if (procedure_ == Procedure::probe_test) {
        // Words 127-129 and bit 249: "The probe test is terminated and new data are available".
        std::normal_distribution<double> spread(0.0, 0.05);
        set_value("probe_resistance", word_of((probe_resistance_kohm + spread(random())) * 100.0));
        set_value("probe_response_time", word_of(probe_response_seconds * 10.0));
        set_value("last_probe_test_temperature", temperature_word(temperature_));
        set_value("change_flag_probe_test_data", 1);
    }
    procedure_ = Procedure::none;
    quiet_since_ = clock_;
}

void Ac20Simulator::raise_change_flag(const std::string& flag) {
    set_value(flag, 1);
    set_value("change_flag_general", 1);
}


// Bits 216/217 (value 1). The manual lists the refusals without saying which applies to which
// procedure: 50-53 are taken to guard both; 54 and 55 concern the probe's output, which only
// the probe test measures, so they guard the probe test. Checked in the listed order.
std::optional<std::uint8_t> Ac20Simulator::procedure_refusal(const Parameter& parameter, std::uint16_t raw) const {
    const bool probe_test = parameter.name == "start_probe_test";
    if (raw == 0 || (!probe_test && parameter.name != "start_burn_off")) return std::nullopt;
    return procedure_refusal_for(probe_test);
}

std::optional<std::uint8_t> Ac20Simulator::procedure_refusal_for(bool probe_test) const {
    if (procedure_ != Procedure::none) return another_procedure;
    if (tune_left_ > 0) return tune_in_progress;
    if (clock_ - quiet_since_ < quiet_period) return too_soon;
    // A thermocouple that cannot be read cannot show the probe hot enough.
    if (fault("open-thermocouple") || fault("reference-junction") || temperature_ < minimum_probe_celsius) {
        return probe_too_cold;
    }
    if (!probe_test) return std::nullopt;
    if (fault("open-probe") || millivolts_ < minimum_probe_mv) return probe_output_low;
    if (probe_drift_per_minute() > maximum_drift) return probe_unstable;
    return std::nullopt;
}


// Bits 210 and 250-259: "The bit resets after reading". Bit 249 (probe test data) has no such
// note; it clears when the next probe test starts. Bit 221 reads as bit 211 OR bit 212.
std::optional<std::uint16_t> Ac20Simulator::flag_read(const Parameter& parameter, std::uint16_t stored) {
    if (parameter.table != Table::coils) return std::nullopt;
    if (parameter.name == "smart_enable") {
        return static_cast<std::uint16_t>(value("tune_status") != 0 || value("adaptive_status") != 0);
    }
    if (parameter.address == 210 || (parameter.address >= 250 && parameter.address <= 259)) {
        if (stored != 0) set_value(parameter.name, 0);
        return stored;
    }
    return std::nullopt;
}


void Ac20Simulator::start_procedure(bool probe_test) {
    procedure_ = probe_test ? Procedure::probe_test : Procedure::burn_off;
    procedure_left_ = probe_test ? probe_test_seconds : std::max(0.0, signed_word(value("burn_off_timer")));
    if (probe_test) set_value("change_flag_probe_test_data", 0);
}

void Ac20Simulator::after_procedure_write(const Parameter& parameter, std::uint16_t raw) {
    const std::string& name = parameter.name;
    if ((name == "start_probe_test" || name == "start_burn_off") && raw == 1) {
        start_procedure(name == "start_probe_test");
        set_value(name, 0);  // a command, not a state
    } else if (name == "burn_off_interval" || name == "probe_test_interval") {
        schedule_interval(name == "probe_test_interval");
    } else if (name == "smart_enable") {
        set_value("tune_status", raw);
        set_value("adaptive_status", raw);
        tune_left_ = raw == 1 ? tune_seconds : 0.0;
    }
}

}  // namespace loopwire::device::models
