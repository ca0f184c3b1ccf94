// Alarms 1-3 on the primary variable (menu groups 3 and 6; words 113-119, bits 204-206, 222),
// and the auxiliary outputs' common off command (bit 233).
#include <cmath>
#include <string>

#include "devices/ac20/ac20_simulator.hpp"
#include "devices/ac20/ac20_words.hpp"

namespace loopwire::device::models {
namespace {

std::string alarm_prefix(int index) { return "alarm_" + std::to_string(index + 1) + "_"; }
std::string band_prefix(int index) { return "band_alarm_" + std::to_string(index + 1) + "_threshold_"; }

// Word 1100: 0 = on the process variable, 1 = band, 2 = deviation. Word 1101: even = high
// alarm, odd = low alarm; 0/1 automatic reset, 2/3 with acknowledge, 4/5 manual reset. Words
// 177-193 give thresholds and hysteresis in the primary variable's raw units. The manual does
// not define the band: taken as set point + band low .. set point + band high, a high band
// alarm going off outside it and a low one inside it. The hysteresis applies on leaving.
struct Zone {
    bool entering = false;
    bool leaving = false;
};

Zone zone_of(const auto& alarm, double pv, double sp) {
    const bool high = alarm.configuration % 2 == 0;
    const double h = alarm.hysteresis;
    if (alarm.type == 1) {
        const double low = sp + alarm.band_low;
        const double top = sp + alarm.band_high;
        const bool outside = pv < low || pv > top;
        const bool well_inside = pv > low + h && pv < top - h;
        const bool inside = !outside;
        const bool well_outside = pv < low - h || pv > top + h;
        return high ? Zone{outside, well_inside} : Zone{inside, well_outside};
    }
    const double x = alarm.type == 2 ? pv - sp : pv;
    return high ? Zone{x > alarm.threshold, x < alarm.threshold - h} : Zone{x < alarm.threshold, x > alarm.threshold + h};
}

}  // namespace

void Ac20Simulator::read_alarm_settings(Settings& settings) const {
    for (int i = 0; i < 3; ++i) {
        auto& alarm = settings.alarms[static_cast<std::size_t>(i)];
        const std::string prefix = alarm_prefix(i);
        alarm.type = value(prefix + "type");
        alarm.configuration = value(prefix + "configuration");
        alarm.action = value(prefix + "action");
        alarm.standby = value(prefix + "standby") == 1;
        alarm.threshold = signed_word(value(prefix + "threshold"));
        alarm.hysteresis = std::abs(signed_word(value(prefix + "hysteresis")));
        alarm.band_low = signed_word(value(band_prefix(i) + "low"));
        alarm.band_high = signed_word(value(band_prefix(i) + "high"));
    }
}

// Word 119 "Variation on alarm status": D8 = 1 on entering, 0 on leaving; D2-D0 the alarm
// number. LED (113-115): 0 off, 1 on, 2 flashing for an alarm waiting for the operator (not
// yet acknowledged, or a manual-reset alarm whose condition has gone). Relay (204-206):
// action Dir (1) energises the relay in alarm, Rev (0) de-energises it.
void Ac20Simulator::update_alarms() {
    const double pv = primary_ * settings_.decimals_scale;
    for (int i = 0; i < 3; ++i) {
        const auto& setting = settings_.alarms[static_cast<std::size_t>(i)];
        AlarmState& alarm = alarms_[static_cast<std::size_t>(i)];
        Zone zone = zone_of(setting, pv, operative_set_point_);
        if (arm_standby_) alarm.standby = setting.standby;
        if (alarm.standby) {  // word 1103: no alarm until the process has first been outside the zone
            if (!zone.entering) alarm.standby = false;
            zone.entering = false;
        }
        if (!alarm.condition && zone.entering) alarm.condition = true;
        if (alarm.condition && zone.leaving) alarm.condition = false;
        const bool manual_reset = setting.configuration >= 4;
        alarm.latched = manual_reset && (alarm.latched || alarm.condition);
        if (!alarm.condition && !manual_reset) alarm.acknowledged = false;
        const bool output = alarm.condition || alarm.latched;
        if (output != alarm.output) {
            alarm.output = output;
            set_value("alarm_status_change", static_cast<std::uint16_t>((output ? 0x100 : 0) | (i + 1)));
        }
        const bool waiting = (setting.configuration == 2 || setting.configuration == 3) ? !alarm.acknowledged
                                                                                         : alarm.latched && !alarm.condition;
        const int led = !output ? 0 : waiting ? 2 : 1;
        const int relay = setting.action == 1 ? output : !output;
        const std::string prefix = alarm_prefix(i);
        if (led != alarm.led) set_value(prefix + "led", static_cast<std::uint16_t>(alarm.led = led));
        if (relay != alarm.relay) set_value(prefix + "relay", static_cast<std::uint16_t>(alarm.relay = relay));
    }
    arm_standby_ = false;
}

void Ac20Simulator::after_alarm_write(const Parameter& parameter, std::uint16_t raw) {
    if (raw == 0) return;
    if (parameter.name == "alarm_reset") {
        // Bit 222 "Manual reset/acknowledge of an alarm condition": acknowledges every alarm in
        // alarm, and releases manual-reset alarms whose condition has gone.
        for (AlarmState& alarm : alarms_) {
            if (alarm.output) alarm.acknowledged = true;
            if (!alarm.condition) alarm.latched = false;
        }
        set_value(parameter.name, 0);
        update_alarms();
    } else if (parameter.name == "deenergize_auxiliary_outputs") {
        // Bit 233 "De-energized all 10 auxiliary outputs": bits 310-319 off.
        for (int output = 10; output <= 19; ++output) set_value("auxiliary_output_" + std::to_string(output), 0);
        set_value(parameter.name, 0);
    }
}

}  // namespace loopwire::device::models
