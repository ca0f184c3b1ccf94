// The start-up error conditions (AC20 manual, "List of error codes" and the paragraphs after
// it): configuration errors 101-106 and control mode errors 151-160 found when the device
// starts, what it still answers and accepts while it shows one, and the 30 s reset.
//
// Choices where the manual is silent:
//  - When: at power-on and at every restart (word 3051), on the next request, so that what
//    --state loaded is what is checked. A configuration menu is in error when its congruence
//    check (Note 7, menu_congruent) fails; a control mode group when one of its words holds a
//    value outside its printed range (a state saved half-way through programming, or edited).
//    Menus are checked before groups; the first failing one is the code.
//  - "Replace the error message with the requested value": a read of configuration, control
//    or security words is answered with the values; any other read (process values, status
//    bits) gets the error code as exception code. A write outside the accepted sets gets it too.
//  - A control mode error is re-checked after every accepted write in control mode (writing a
//    good value or loading the group's defaults clears it); a configuration error is cleared
//    by fixing the menu and leaving configuration mode through 3051 (a restart).
//  - "No action is taken": no write accepted for 30 s of protocol time (never --speed). The
//    reset is a power-on: control mode, local (Note 5), RAM values lost, checked again.
//  - Calibration errors 200-208 are not simulated (there is no calibration to get wrong).
#include <chrono>

#include "devices/ac20/ac20_simulator.hpp"
#include "profile/values.hpp"

namespace loopwire::device::models {
namespace {

constexpr auto reset_timeout = std::chrono::seconds(30);
constexpr std::uint8_t first_configuration_error = 100;  // + menu 1-6
constexpr std::uint8_t first_control_error = 150;        // + group 1-9; hidden = 160
constexpr int hidden_group_error = 160;
constexpr std::uint16_t dont_care = 0x8000;

}  // namespace

// Configuration: the menus' words and the words written in configuration mode (3000-3005,
// 3050, 3051); security: the words written in security code mode (4000-4011); control: the
// control mode menus' words, not the outputs 130-132 and commands around them. A word that
// gives one of them its decimal point (word 300: "See Mbus Word 300") belongs with it: a value
// is no value without it.
Ac20Simulator::Area Ac20Simulator::area_of(const Parameter& parameter) const {
    const auto own_area = [this](const Parameter& p) {
        if (configuration_menu_of(p) || p.writable_in("configuration")) return Area::configuration;
        if (p.writable_in("security")) return Area::security;
        if (control_group_of(p)) return Area::control;
        return Area::other;
    };
    const Area area = own_area(parameter);
    if (area != Area::other) return area;
    for (const Parameter& user : profile().parameters) {
        const auto* source = std::get_if<std::string>(&user.decimals);
        if (source != nullptr && *source == parameter.name && own_area(user) != Area::other) return own_area(user);
    }
    return Area::other;
}

std::optional<std::uint8_t> Ac20Simulator::start_up_error() const {
    for (int menu = 1; menu <= 6; ++menu) {
        if (!menu_congruent(menu)) return static_cast<std::uint8_t>(first_configuration_error + menu);
    }
    for (const Parameter& parameter : profile().parameters) {
        const auto group = control_group_of(parameter);
        if (!group || !parameter.writable || (!parameter.min && !parameter.max)) continue;
        const std::uint16_t raw = value(parameter.name);
        if (raw == dont_care || raw_in_range(parameter, raw, memory().known_for(parameter, {}))) continue;
        return static_cast<std::uint8_t>(*group == 0 ? hidden_group_error : first_control_error + *group);
    }
    return std::nullopt;
}

// Runs first on every request: the check a restart asked for, and the 30 s reset.
void Ac20Simulator::track_error_condition() {
    const auto now = environment().now();
    if (error_condition_ && mode_ != Mode::configuration && now - error_since_ > reset_timeout) {
        restart();
        set_remote(false);  // Note 5: powered up from control mode, so local
    }
    if (!start_up_check_due_) return;
    start_up_check_due_ = false;
    error_condition_ = start_up_error();
    error_since_ = now;
}

bool Ac20Simulator::is_configuration_error() const {
    return error_condition_ && *error_condition_ < first_control_error;
}

// Reads (FC1-FC4 within the limits; the rest is the base's to refuse) that touch a mapped word
// outside the configuration, control and security areas.
std::optional<Bytes> Ac20Simulator::error_condition_read_refusal(ByteView request_pdu) {
    if (!error_condition_) return std::nullopt;
    for (const Parameter* parameter : parameters_read_by(request_pdu)) {
        if (area_of(*parameter) == Area::other) return Bytes{static_cast<std::uint8_t>(request_pdu[0] | 0x80), *error_condition_};
    }
    return std::nullopt;
}

// The accepted sets: bit 218, words 347 and 348, the configuration and security words; with a
// control mode error also the control mode words and the load-default bits 223-232.
std::optional<std::uint8_t> Ac20Simulator::error_condition_refusal(const Parameter& parameter) const {
    if (!error_condition_) return std::nullopt;
    const std::string& name = parameter.name;
    if (name == "local_remote" || name == "configuration_mode_code" || name == "security_mode_code") return std::nullopt;
    const Area area = area_of(parameter);
    if (area == Area::configuration || area == Area::security) return std::nullopt;
    const bool load_default_bit = parameter.table == Table::coils && parameter.address >= 223 && parameter.address <= 232;
    if (!is_configuration_error() && (area == Area::control || load_default_bit)) return std::nullopt;
    return *error_condition_;
}

void Ac20Simulator::after_error_condition_write() {
    if (!error_condition_) return;
    error_since_ = environment().now();  // an action: the reset time-out starts again
    if (!is_configuration_error() && mode_ == Mode::control) error_condition_ = start_up_error();
}

}  // namespace loopwire::device::models
