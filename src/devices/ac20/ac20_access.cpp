// Who may write what, and when (AC20 manual Notes 5-9 and the N.B. after Note 9).
#include <algorithm>
#include <array>
#include <chrono>
#include <string_view>

#include "devices/ac20/ac20_simulator.hpp"

namespace loopwire::device::models {
namespace {

// Error reply, code 10: "The bit or word indicated cannot be modified". The manual names no
// other code for a write refused by the device's state, so local mode (Note 5), the wrong
// mode (Notes 6-8), a locked group (Note 9) and a combination of 1 ("no value will be
// accepted", Note 8) all answer 10.
constexpr std::uint8_t cannot_modify = 10;
// Code 3, "Illegal data value": a mode-entry word written with a value that is not the
// safety lock combination (the word could be modified, the value given is the wrong one).
constexpr std::uint8_t wrong_value = 3;

// Note 5: "If there is no line activity for more than 3 sec. every slave will automatically
// return to local mode."
constexpr auto remote_timeout = std::chrono::seconds(3);

// What the lock words read for a combination (words 347/348/4000/4001): 0 = free, 1 = always
// locked, 2 = locked by a software key (N.B. after Note 9: combinations 0, 1 and 2-250).
std::uint16_t combination_class(std::uint16_t combination) { return combination <= 1 ? combination : 2; }

// Control-mode menu groups in the order of the lock words 350-359, flags 250-259 and
// protection words 4002-4011: hidden, 1 .. 9 (group 2 has no words; group 9 is the auxiliary
// outputs, bit 259). Profile group names are the menu mnemonics.
constexpr std::array<std::pair<std::string_view, int>, 8> control_groups{{
    {"Hidn", 0}, {"St.Pn", 1}, {"Alrñ", 3}, {"Cntr", 4}, {"A.Ctr", 5}, {"A.SEt", 6}, {"Sr.Ln", 7}, {"tiñE", 8}}};

std::string group_suffix(int group) { return group == 0 ? "hidden" : std::to_string(group); }

}  // namespace

// "Line activity" is any frame on the line: every request this simulator receives (addressed
// to it or broadcast, answered or not), and, through the slave session (on_line_activity), every
// frame for the other units of its line and bytes that fail their check (bytes on the line are
// activity; the manual does not ask for a valid frame). The timeout is protocol time
// (environment().now()), never scaled by --speed.
void Ac20Simulator::note_line_activity() {
    const auto now = environment().now();
    if (remote_ && now - last_activity_ > remote_timeout) set_remote(false);
    last_activity_ = now;
}

void Ac20Simulator::on_line_activity() { note_line_activity(); }

void Ac20Simulator::set_remote(bool remote) {
    if (remote != remote_) condition_changed();
    remote_ = remote;
    set_value("local_remote", remote ? 1 : 0);
}

void Ac20Simulator::set_mode(Mode mode) {
    if (mode != mode_) condition_changed();
    mode_ = mode;
}

// Note 5: "At power up, the slave will be in local mode if it was in control mode at power off.
// In the other cases, it will maintain the condition it was at the power off." The condition
// kept is the mode (0 control, 1 configuration, 2 security code, as Mode) and bit 218.
// The fall-back to local is noticed at the next frame; a save before it already says local.
RawValues Ac20Simulator::condition_at_power_off() const {
    const bool remote = remote_ && environment().now() - last_activity_ <= remote_timeout;
    return {{"mode", static_cast<std::uint16_t>(mode_)}, {"remote", remote ? std::uint16_t{1} : std::uint16_t{0}}};
}

void Ac20Simulator::restore_condition(const RawValues& condition) {
    const auto mode = condition.find("mode");
    const auto remote = condition.find("remote");
    if (mode == condition.end() || (mode->second != static_cast<std::uint16_t>(Mode::configuration) &&
                                    mode->second != static_cast<std::uint16_t>(Mode::security))) {
        // Control mode, or nothing kept (a file from before): local, whatever bit 218 was saved as.
        set_remote(false);
        return;
    }
    set_mode(static_cast<Mode>(mode->second));
    set_remote(remote != condition.end() && remote->second != 0);
    last_activity_ = environment().now();  // the 3 s fall-back (Note 5) counts from power-up
}

std::optional<std::uint8_t> Ac20Simulator::access_refusal(const Parameter& parameter, std::uint16_t raw) {
    // Note 5: in local "the communication ... is limited to transferring data from slave to
    // master ... (with the exception of the local/remote status bit)".
    if (parameter.name == "local_remote") return std::nullopt;
    if (!remote_) return cannot_modify;
    // Notes 7, 8: configuration and security code mode are entered from remote with the
    // configuration-mode safety lock combination; N.B.: word 349 locks and unlocks.
    if (parameter.name == "configuration_mode_code" || parameter.name == "security_mode_code") {
        return mode_entry_refusal(raw);
    }
    if (parameter.writable_in("remote")) return std::nullopt;
    if (parameter.writable_in("configuration") && mode_ == Mode::configuration) return std::nullopt;
    if (parameter.writable_in("security") && mode_ == Mode::security) return std::nullopt;
    // Note 6: control-mode writes need control mode, remote and the unlock condition.
    if (parameter.writable_in("control") && mode_ == Mode::control) {
        const auto group = control_group_of(parameter);
        if (group && group_locked(*group)) return cannot_modify;
        return std::nullopt;
    }
    return cannot_modify;
}

// Note 8 footnote: "If the value of safety lock combination for configuration mode is 0, all
// values will be accepted. If the value is 1, no value will be accepted." Otherwise only the
// combination itself (word 4000) opens the mode.
std::optional<std::uint8_t> Ac20Simulator::mode_entry_refusal(std::uint16_t raw) const {
    const std::uint16_t combination = value("configuration_lock_combination");
    if (combination == 0) return std::nullopt;
    if (combination == 1) return cannot_modify;
    return raw == combination ? std::nullopt : std::optional<std::uint8_t>(wrong_value);
}

std::optional<int> Ac20Simulator::control_group_of(const Parameter& parameter) const {
    if (parameter.table == Table::coils && parameter.address >= 310 && parameter.address <= 319) return 9;
    for (const auto& [name, group] : control_groups) {
        if (parameter.group == name) return group;
    }
    return std::nullopt;
}

// N.B. after Note 9: control combination (word 4001) 0 = nothing protected, 1 = everything
// protected; 2-250 = the groups marked in 4002-4011 are protected until word 349 receives the
// combination ("It is sufficient to do this once only").
bool Ac20Simulator::group_locked(int group) const {
    const std::uint16_t combination = value("control_lock_combination");
    if (combination <= 1) return combination == 1;
    return value("protect_group_" + group_suffix(group)) == 1 && !control_unlocked_;
}

std::optional<std::uint16_t> Ac20Simulator::lock_word_read(const Parameter& parameter, std::uint16_t stored) const {
    const std::uint16_t control_combination = value("control_lock_combination");
    const std::uint16_t key_state = control_unlocked_ ? 3 : 2;  // word 349: 2 locked, 3 unlocked
    const std::string& name = parameter.name;
    if (name == "configuration_mode_code" || name == "security_mode_code") {
        return combination_class(value("configuration_lock_combination"));
    }
    // Words 4000/4001 read the class, never the key (security table "Reading: 0/1/2").
    if (name == "configuration_lock_combination" || name == "control_lock_combination") {
        return combination_class(stored);
    }
    const std::uint16_t control_class = combination_class(control_combination);
    if (name == "control_lock_code") return control_class == 2 ? key_state : control_class;
    if (name == "device_lock_status") {  // bit 213: 1 while anything is locked
        const bool any = control_class == 1 || (control_class == 2 && !control_unlocked_);
        return any ? 1 : 0;
    }
    if (parameter.table == Table::holding_registers && parameter.address >= 350 && parameter.address <= 359) {
        const int group = parameter.address - 350;
        if (control_class != 2) return control_class;
        return value("protect_group_" + group_suffix(group)) == 1 ? key_state : 0;
    }
    // N.B.: with combination 0 or 1, words 4002-4011 are forced to 0 or 1.
    if (parameter.table == Table::holding_registers && parameter.address >= 4002 && parameter.address <= 4011 &&
        control_class != 2) {
        return control_class;
    }
    return std::nullopt;
}

void Ac20Simulator::after_access_write(const Parameter& parameter, std::uint16_t raw) {
    const std::string& name = parameter.name;
    if (name == "local_remote") {
        set_remote(raw != 0);
    } else if (name == "configuration_mode_code") {
        set_mode(Mode::configuration);  // display "SEr COnF" (Note 7)
        open_menu_.reset();
    } else if (name == "security_mode_code") {
        set_mode(Mode::security);  // display "Scrt COnF" (Note 8)
    } else if (name == "control_lock_code") {
        const std::uint16_t combination = value("control_lock_combination");
        control_unlocked_ = combination >= 2 && raw == combination;
    } else if (name == "control_lock_combination") {
        control_unlocked_ = false;  // a new key locks again
        if (raw <= 1) {
            for (int group = 0; group <= 9; ++group) store_default("protect_group_" + group_suffix(group), raw);
        }
    } else if (name == "enable_control_mode") {
        // Notes 7, 8: "The slave will reset and restart in control mode condition." Note 5: it
        // was not in control mode, so it keeps its remote state across the restart.
        restart();
    }
}

// Power-on and the restart after word 3051: control mode, Smart and procedures stopped, the
// RAM-only operative set point (word 137) lost, bit 210 set "to signal the start up", and the
// start-up error check due.
void Ac20Simulator::restart() {
    set_mode(Mode::control);
    open_menu_.reset();
    procedure_ = Procedure::none;
    tune_left_ = 0;
    quiet_since_ = clock_;  // error 52: 5 minutes from power on
    set_value("tune_status", 0);
    set_value("adaptive_status", 0);
    operative_set_point_type_ = last_selection_ = selected_set_point();
    operative_set_point_ = static_cast<std::int16_t>(set_point_word(operative_set_point_type_));
    set_value("operative_set_point", static_cast<std::uint16_t>(operative_set_point_));
    set_value("manufacturer_trade_mark", 50);
    set_value("device_identification_code", identification_code);
    set_value("change_flag_general", 1);
    arm_standby_ = true;
    schedule_interval(false);
    schedule_interval(true);
    settings_dirty_ = true;
    start_up_check_due_ = true;  // ac20_error_condition.cpp
}

}  // namespace loopwire::device::models
