// The furnace, its measurement and the carbon controller.
#include <algorithm>
#include <cmath>
#include <random>

#include "devices/ac20/ac20_atmosphere.hpp"
#include "devices/ac20/ac20_simulator.hpp"
#include "devices/ac20/ac20_words.hpp"

namespace loopwire::device::models {
namespace {

constexpr std::uint8_t cannot_modify = 10;
constexpr std::uint16_t not_available = 0x8000;  // FC3/4: "not relevant in the actual device configuration"
constexpr int no_step = 0x7FFF;


constexpr double furnace_output = 0.9;
constexpr double noise_mv = 0.1;
constexpr double noise_celsius = 0.2;

const ac20::Gas furnace_gas{0.20, 0.40};  // what the endothermic carrier really holds


}  // namespace

void Ac20Simulator::refresh_settings() {
    settings_dirty_ = false;
    Settings s;
    s.primary = value("primary_variable_selection");
    s.fahrenheit = value("temperature_input_type") >= 4;
    const int decimals = s.primary == 0 ? 2 : 0;  // 0.00-2.00 %C; dew point and mV whole units (word 2001)
    set_value("primary_variable_decimals", static_cast<std::uint16_t>(decimals));
    set_value("main_output_display_decimals", value("main_output_scaling") ? value("main_output_decimal_point") : 1);
    set_value("secondary_output_display_decimals",
              value("secondary_output_scaling") ? value("secondary_output_decimal_point") : 1);
    s.decimals_scale = std::pow(10.0, decimals);
    s.pid.proportional_band = signed_word(value("proportional_band")) / 10.0;
    s.pid.integral_time = value("integral_time") == no_step ? 0.0 : signed_word(value("integral_time"));
    // Word 2301: 1 = PI actions only.
    s.pid.derivative_time = value("control_action_type") == 1 ? 0.0 : signed_word(value("derivative_time"));
    s.pid.span = s.primary == 0 ? 2.0 : s.primary == 1 ? (s.fahrenheit ? 200.0 : 115.0) : 1500.0;
    s.pid.hysteresis = s.pid.span * signed_word(value("on_off_hysteresis")) / 1000.0;  // % of span, 1 decimal
    s.output_low = signed_word(value("main_output_low_limit")) / 10.0;
    s.output_high = signed_word(value("main_output_high_limit")) / 10.0;
    s.complement = value("main_output_conditioning") == 1;
    s.rate_up = value("set_point_rate_positive") == no_step ? -1.0 : signed_word(value("set_point_rate_positive"));
    s.rate_down = value("set_point_rate_negative") == no_step ? -1.0 : signed_word(value("set_point_rate_negative"));
    if (value("carbon_monoxide_factor") > 0) s.carbon_monoxide = value("carbon_monoxide_factor") / 100.0;
    if (value("hydrogen_factor") > 0) s.hydrogen = value("hydrogen_factor") / 100.0;
    read_alarm_settings(s);
    settings_ = s;
    pid_.set_settings(s.pid);
}

bool Ac20Simulator::measurement_fault() const {
    return fault("open-probe") || fault("open-thermocouple") || fault("reference-junction") || fault("auto-zero");
}

// The inputs the AC20 sees: probe mV and thermocouple °C, with a little noise, through the
// probe filter (word 2002, seconds). During burn-off, purge and probe test the probe is not
// measuring the atmosphere; the AC20 is taken to hold its last readings (and its output).
void Ac20Simulator::measure(double seconds) {
    furnace_.step(seconds, fault("heater-failure") ? 0.0 : furnace_output);
    atmosphere_.step(seconds, main_output_ / 100.0);
    if (procedure_ != Procedure::none && seconds > 0) return;
    // An air leak burns the carbon off the atmosphere (it reads as a lean, low-mV gas).
    const double carbon = std::max(0.001, atmosphere_.temperature() * (fault("air-leak") ? 0.02 : 1.0));
    const double celsius = furnace_.temperature();
    const double mv = ac20::probe_millivolts(ac20::oxygen_pressure_for_carbon(carbon, celsius, furnace_gas), celsius);
    std::normal_distribution<double> mv_noise(0.0, noise_mv);
    std::normal_distribution<double> t_noise(0.0, noise_celsius);
    const double filter = std::max(0.0, signed_word(value("probe_input_filter")));
    const double weight = seconds <= 0 ? 1.0 : 1.0 - std::exp(-seconds / std::max(filter, 1e-3));
    millivolts_ += weight * (mv + mv_noise(random()) - millivolts_);
    temperature_ = celsius + t_noise(random());
    if (millivolt_history_.empty() || clock_ - millivolt_history_.back().first >= 1.0) {
        millivolt_history_.emplace_back(clock_, millivolts_);
    }
    while (!millivolt_history_.empty() && clock_ - millivolt_history_.front().first > 60.0) {
        millivolt_history_.pop_front();
    }
}

double Ac20Simulator::probe_drift_per_minute() const {
    if (millivolt_history_.size() < 2) return 0;
    const double minutes = (millivolt_history_.back().first - millivolt_history_.front().first) / 60.0;
    if (minutes <= 0) return 0;
    return std::abs(millivolt_history_.back().second - millivolt_history_.front().second) / minutes;
}

// The primary variable (word 2001) in engineering units, computed from the two inputs.
double Ac20Simulator::primary_value() const {
    if (settings_.primary == 2) return millivolts_;
    const auto reading = ac20::read_probe(millivolts_, temperature_, {settings_.carbon_monoxide, settings_.hydrogen});
    if (settings_.primary == 1) return celsius_to_unit(reading.dew_point_celsius, settings_.fahrenheit);
    return reading.carbon_percent;
}

// Operative set point (words 136/137): the set point the contacts select (SP, SP2-SP4,
// ac20_contacts.cpp) through the gradients 1013/1014
// (raw units per minute; 7FFFh = step), or the value written to word 137, which "will not be
// influenced by the gradient mechanism". PID on the primary variable; a dew point falls as
// the atmosphere gets richer, so it is controlled reverse-acting. Manual (bit 219) holds the
// output; a procedure holds it too; a measurement fault drops it to its low limit (no
// enrichment: the safe side for a carburising atmosphere).
void Ac20Simulator::control(double seconds) {
    if (operative_set_point_type_ != 0) {
        const double target = signed_word(set_point_word(operative_set_point_type_));
        const double rate = target > operative_set_point_ ? settings_.rate_up : settings_.rate_down;
        const double step = rate < 0 ? std::abs(target - operative_set_point_) : rate * seconds / 60.0;
        operative_set_point_ += std::clamp(target - operative_set_point_, -step, step);
    }
    const double sp = operative_set_point_ / settings_.decimals_scale;
    const double pv = primary_ = primary_value();
    const double direction = settings_.primary == 1 ? -1.0 : 1.0;
    if (measurement_fault()) {
        main_output_ = pid_output_ = settings_.output_low;
        pid_.track(pid_output_, direction * sp, direction * pv);
    } else if (manual_ || procedure_ != Procedure::none) {
        pid_.track(pid_output_, direction * sp, direction * pv);
    } else {
        pid_output_ = pid_.step(seconds, direction * sp, direction * pv);
    }
    if (!manual_) {
        main_output_ = std::clamp(pid_output_, settings_.output_low, settings_.output_high);
        if (settings_.complement) main_output_ = 100.0 - main_output_;
    }
}

std::uint16_t Ac20Simulator::temperature_word(double celsius) const {
    return word_of(celsius_to_unit(celsius, settings_.fahrenheit));
}

// Note 6: writes are accepted only "if they are meaningful in the present contest".
std::optional<std::uint8_t> Ac20Simulator::context_refusal(const Parameter& parameter, std::uint16_t raw) const {
    const std::string& name = parameter.name;
    // Bit 219 manual needs the manual function (word 2302); word 130 sets the output only in
    // manual; 131 (no secondary output is configured) and 132 (computed) are never meaningful.
    if (name == "auto_manual" && raw == 1 && value("manual_function") == 0) return cannot_modify;
    if (name == "main_output_value" && !manual_) return cannot_modify;
    if (name == "secondary_output_value" || name == "pid_output_value") return cannot_modify;
    // Bit 221 enables Smart only where word 2300 says "Smart function may be enabled".
    if (name == "smart_enable" && raw == 1 && value("smart_function") == 0) return cannot_modify;
    return std::nullopt;
}

void Ac20Simulator::after_process_write(const Parameter& parameter, std::uint16_t raw) {
    const std::string& name = parameter.name;
    if (name == "auto_manual") {
        const bool to_manual = raw == 1 && !manual_;
        manual_ = raw == 1;
        // Word 2303: the output on transfer to manual, 7FFFh = bumpless (keep the output).
        if (to_manual && value("auto_manual_transfer_output") != no_step) {
            main_output_ = pid_output_ = signed_word(value("auto_manual_transfer_output")) / 10.0;
        }
    } else if (name == "main_output_value") {
        main_output_ = pid_output_ = std::clamp(signed_word(raw) / 10.0, 0.0, 100.0);
    } else if (parameter.table == Table::holding_registers && parameter.address >= 138 && parameter.address <= 141 &&
               parameter.address - 137 == selected_set_point()) {
        operative_set_point_type_ = selected_set_point();  // the selected set point written ends a word-137 value
    } else if (name == "operative_set_point") {
        operative_set_point_ = signed_word(raw);
        operative_set_point_type_ = 0;
    }
}

// Process words, computed when read. Note 6: variables are "available only if the device is
// in control mode": in configuration or security code mode they read 8000h. A measurement
// error puts the manual's code in the word (words 122-126); a value the failed input makes
// impossible to compute, where the word lists no code for it, reads 8000h ("not relevant").
std::optional<std::uint16_t> Ac20Simulator::process_read(const Parameter& parameter) const {
    if (parameter.table != Table::holding_registers) return std::nullopt;
    const std::uint16_t address = parameter.address;
    if (address == 135) {
        if (mode_ == Mode::configuration) return 6;
        if (mode_ == Mode::security) return 7;
        return procedure_ == Procedure::burn_off ? 3 : procedure_ == Procedure::purge ? 4
               : procedure_ == Procedure::probe_test ? 5 : 0;
    }
    const bool process_word = (address >= 122 && address <= 134) || address == 136 || address == 137;
    if (!process_word) return std::nullopt;
    if (mode_ != Mode::control) return not_available;
    const bool zero_error = fault("auto-zero");
    const bool probe_open = fault("open-probe");
    const bool thermocouple_bad = fault("open-thermocouple") || fault("reference-junction");
    const auto reading = ac20::read_probe(millivolts_, temperature_, {settings_.carbon_monoxide, settings_.hydrogen});
    switch (address) {
        case 122: return zero_error ? 30050 : probe_open ? 30005 : word_of(millivolts_);
        case 123:
            if (zero_error) return 30050;
            return probe_open || thermocouple_bad ? not_available : word_of(reading.carbon_percent * 100.0);
        case 124:
            if (zero_error) return 30050;
            return probe_open || thermocouple_bad ? not_available : temperature_word(reading.dew_point_celsius);
        case 125:
            if (zero_error) return 30050;
            if (fault("open-thermocouple")) return 30002;
            return fault("reference-junction") ? 30014 : temperature_word(temperature_);
        case 126:
            if (value("auxiliary_input_function") == 0) return not_available;
            return zero_error ? 30050 : word_of(furnace_gas.carbon_monoxide * 100.0);
        case 130: return word_of(main_output_ * 10.0);
        case 131: return 0;
        case 132: return word_of(pid_output_ * 10.0);
        case 133: {
            // Word 2206: the output shown in engineering units between 2208 and 2209.
            if (value("main_output_scaling") == 0) return word_of(main_output_ * 10.0);
            const double low = signed_word(value("main_output_display_low"));
            const double high = signed_word(value("main_output_display_high"));
            return word_of(low + (high - low) * main_output_ / 100.0);
        }
        case 134: return 0;
        case 136: return static_cast<std::uint16_t>(operative_set_point_type_);
        case 137: return word_of(operative_set_point_);
        default: return std::nullopt;  // 127-129: stored by the last probe test
    }
}

}  // namespace loopwire::device::models
