// Configuration menus (Note 7), default tables (word 3050, bits 223-232).
#include <array>
#include <span>
#include <string_view>
#include <utility>

#include "devices/ac20/ac20_simulator.hpp"

namespace loopwire::device::models {
namespace {

constexpr std::uint8_t cannot_modify = 10;
constexpr int no_step = 0x7FFF;  // 7FFFh: "no ramp limitation", "step change", "no interval", "bumpless"

using Default = std::pair<std::string_view, int>;
using Defaults = std::span<const Default>;

// The manual names the two tables only ("TB1 = European table", "TB2 = American table") and
// gives no values. Chosen here: a carbon-potential controller on a type K thermocouple, main
// control output on Out 1, alarms on Out 2/3, Smart and manual function available. TB2 differs
// in line frequency (60 Hz) and temperature unit (°F, word 2003 = 4).
constexpr Default configuration_defaults[]{
    {"line_frequency", 0}, {"primary_variable_selection", 0}, {"probe_input_filter", 2},
    {"temperature_input_type", 1}, {"temperature_input_offset", 0}, {"temperature_filter", 2},
    {"auxiliary_input_function", 0}, {"auxiliary_input_type", 1},
    {"out_1_function", 1}, {"out_2_function", 3}, {"out_3_function", 3},
    {"out_6_function", 0}, {"out_6_range", 1}, {"out_6_retransmission_low", 0}, {"out_6_retransmission_high", 200},
    {"out_6_filter", 0}, {"out_7_function", 0}, {"out_7_range", 1}, {"out_7_retransmission_low", 0},
    {"out_7_retransmission_high", 200}, {"out_7_filter", 0},
    {"main_output_conditioning", 0}, {"main_output_scaling", 0}, {"main_output_decimal_point", 1},
    {"main_output_display_low", 0}, {"main_output_display_high", 1000}, {"main_output_auxiliary_conditioning", 0},
    {"secondary_output_conditioning", 0}, {"secondary_output_scaling", 0}, {"secondary_output_decimal_point", 1},
    {"secondary_output_display_low", 0}, {"secondary_output_display_high", 1000},
    {"secondary_output_auxiliary_conditioning", 0},
    {"smart_function", 1}, {"control_action_type", 0}, {"manual_function", 1},
    {"auto_manual_transfer_output", no_step}, {"manual_auto_transfer_type", 0}, {"start_up_status", 0},
    {"dig1_function", 0}, {"dig1_polarity", 1}, {"dig2_function", 0}, {"dig2_polarity", 1}, {"dig3_polarity", 1},
    {"green_bar_graph", 0}, {"orange_bar_graph", 0}, {"bar_graph_low", 0}, {"bar_graph_high", 200},
    {"deviation_bar_graph_resolution", 1}, {"set_point_display_type", 0}, {"temperature_threshold_activation", 0},
    {"timeout_selection", 0}};
constexpr Default american_differences[]{{"line_frequency", 1}, {"temperature_input_type", 4}};

// Control-mode defaults per group (hidden, 1 .. 8), values raw for the carbon-potential
// primary variable (2 decimals). The manual gives none; chosen for a carburising furnace:
// 0.80 %C set point, a 10 % band and 2 min integral on the 0-2.00 %C span.
Defaults control_defaults(int group) {
    static constexpr Default hidden[]{{"smart_proportional_band_min", 10}, {"smart_proportional_band_max", 500},
                                     {"smart_integral_time_min", 30}, {"smart_integral_time_max", 1200},
                                     {"smart_relative_secondary_gain", 0}};
    static constexpr Default set_points[]{{"main_set_point", 80}, {"auxiliary_set_point_2", 80},
                                         {"auxiliary_set_point_3", 80}, {"auxiliary_set_point_4", 80},
                                         {"carbon_monoxide_factor", 20}, {"hydrogen_factor", 40}};
    static constexpr Default alarms[]{
        {"alarm_1_threshold", 120}, {"alarm_2_threshold", 40}, {"alarm_3_threshold", 150},
        {"band_alarm_1_threshold_low", 0}, {"band_alarm_1_threshold_high", 0}, {"band_alarm_2_threshold_low", 0},
        {"band_alarm_2_threshold_high", 0}, {"band_alarm_3_threshold_low", 0}, {"band_alarm_3_threshold_high", 0},
        {"alarm_1_hysteresis", 1}, {"alarm_2_hysteresis", 1}, {"alarm_3_hysteresis", 1}};
    static constexpr Default control[]{{"proportional_band", 100}, {"on_off_hysteresis", 5}, {"integral_time", 120},
                                      {"derivative_time", 0}, {"integral_preload", 0},
                                      {"relative_secondary_output_gain", 100}, {"dead_band_overlap", 0}};
    static constexpr Default auxiliary[]{
        {"anti_reset_windup", 100}, {"main_output_low_limit", 0}, {"main_output_high_limit", 1000},
        {"main_output_max_rate_of_rise", no_step}, {"main_output_cycle_time", 20},
        {"secondary_output_low_limit", 0}, {"secondary_output_high_limit", 1000},
        {"secondary_output_max_rate_of_rise", no_step}, {"secondary_output_cycle_time", 20},
        {"set_point_low_limit", 0}, {"set_point_high_limit", 200}, {"set_point_rate_positive", no_step},
        {"set_point_rate_negative", no_step}, {"external_auto_manual_control", 0}};
    static constexpr Default alarm_setting[]{
        {"alarm_1_type", 0}, {"alarm_1_configuration", 0}, {"alarm_1_action", 0}, {"alarm_1_standby", 0},
        {"alarm_2_type", 0}, {"alarm_2_configuration", 1}, {"alarm_2_action", 0}, {"alarm_2_standby", 0},
        {"alarm_3_type", 0}, {"alarm_3_configuration", 0}, {"alarm_3_action", 0}, {"alarm_3_standby", 0}};
    // Group 7: the device address (527) is the unit the simulator serves, so it is left alone.
    static constexpr Default serial[]{{"serial_interface_protocol", 1}, {"serial_baud_rate", 5}, {"serial_byte_format", 0}};
    static constexpr Default timers[]{{"burn_off_timer", 90}, {"purge_timer", 60}, {"burn_off_interval", no_step},
                                     {"probe_test_interval", no_step}};
    switch (group) {
        case 0: return hidden;
        case 1: return set_points;
        case 3: return alarms;
        case 4: return control;
        case 5: return auxiliary;
        case 6: return alarm_setting;
        case 7: return serial;
        case 8: return timers;
        default: return {};
    }
}

// Configuration menus 1-6 by the profile's group names (menu mnemonics).
constexpr std::array<std::pair<std::string_view, int>, 6> configuration_menus{
    {{"Inpt.", 1}, {"Out.", 2}, {"C.Cn.", 3}, {"AC.Cn.", 4}, {"In.Ot.", 5}, {"Othr.", 6}}};

}  // namespace

void Ac20Simulator::store_default(std::string_view name, int raw) {
    set_value(name, static_cast<std::uint16_t>(raw), Persistence::saved);
}

std::optional<int> Ac20Simulator::configuration_menu_of(const Parameter& parameter) {
    for (const auto& [name, menu] : configuration_menus) {
        if (parameter.group == name) return menu;
    }
    return std::nullopt;
}

// Note 7: writing 1 to word 3000-3005 ends a configuration menu and checks "the congruence of
// the programmed data compared with the data of the other configuration menus ... the reply
// will include a 1xx error message where xx represents the number of the menus whose closure
// has caused the error". "The end of the group programming is anyway automatically sent if
// data of a different menu are programmed ... and if the output of the configuration mode is
// imposed": a write to another menu's word, or to word 3051, first closes the open menu and
// is refused with that menu's 1xx error if the check fails (the write is not executed).
// Reads: see menu_read_refusal.
std::optional<std::uint8_t> Ac20Simulator::configuration_refusal(const Parameter& parameter, std::uint16_t) {
    if (mode_ != Mode::configuration) return std::nullopt;
    auto closing_error = [](int menu) { return static_cast<std::uint8_t>(100 + menu); };
    if (parameter.table == Table::holding_registers && parameter.address >= 3000 && parameter.address <= 3005) {
        const int menu = parameter.address - 3000 + 1;
        return menu_congruent(menu) ? std::nullopt : std::optional<std::uint8_t>(closing_error(menu));
    }
    const auto menu = configuration_menu_of(parameter);
    const bool leaves_menu = parameter.name == "enable_control_mode" || (menu && menu != open_menu_);
    if (open_menu_ && leaves_menu && !menu_congruent(*open_menu_)) return closing_error(*open_menu_);
    return std::nullopt;
}

// The parameters a read request (FC1-FC4, within the per-request limits) touches, in order;
// none for any other request (the base answers or refuses it). The wire address is the
// profile's own plus 1 under J-BUS numbering (word 526 = 2).
std::vector<const Parameter*> Ac20Simulator::parameters_read_by(ByteView request_pdu) {
    std::vector<const Parameter*> touched;
    if (request_pdu.size() != 5 || request_pdu[0] < 1 || request_pdu[0] > 4) return touched;
    const bool bits = request_pdu[0] <= 2;
    const std::uint16_t start = read_be16(request_pdu, 1);
    const std::uint16_t count = read_be16(request_pdu, 3);
    const std::uint16_t offset = value("serial_interface_protocol") == 2 ? 1 : 0;
    if (count > (bits ? profile().limits.read_bits : profile().limits.read_registers) || start < offset) return touched;
    for (unsigned i = 0; i < count; ++i) {
        const auto address = static_cast<std::uint16_t>(start - offset + i);
        if (const MemoryCell* cell = memory().find(bits ? Table::coils : Table::holding_registers, address)) touched.push_back(cell->parameter);
    }
    return touched;
}

// Note 7: the end of the programming of a menu "is anyway automatically sent if data of a
// different menu are ... read": a read (FC3/FC4, within the 20-word limit) that touches a word
// of another configuration menu closes the open one first, and answers its 1xx error if the
// check fails.
std::optional<Bytes> Ac20Simulator::menu_read_refusal(ByteView request_pdu) {
    if (mode_ != Mode::configuration || !open_menu_) return std::nullopt;
    for (const Parameter* parameter : parameters_read_by(request_pdu)) {
        const auto menu = configuration_menu_of(*parameter);
        if (!menu || menu == open_menu_) continue;
        if (!menu_congruent(*open_menu_)) {
            return Bytes{static_cast<std::uint8_t>(request_pdu[0] | 0x80), static_cast<std::uint8_t>(100 + *open_menu_)};
        }
        open_menu_.reset();
        return std::nullopt;
    }
    return std::nullopt;
}

// The manual states no congruence rules; these follow from what its tables say the words
// mean. Scales are raw, in the primary variable's decimals.
//  1: the primary variable (2001) fixes a span (0.00-2.00 %C, -75..40 °C / -100..100 °F dew
//     point, 0-1500 mV); retransmission scales in use (menu 2) and the bar graph (menu 6) must
//     lie inside it.
//  2: a retransmitting output (function 3 or 4) needs low < high inside that span.
//  3: a scaled output display (2206/2212 = 1) needs low < high.
//  4: "starts always in manual mode" (2305 = 1) needs the manual function (2302 = 1).
//  5: a DIG input for auto/manual (function 3) needs the manual function (menu 4), and DIG1
//     and DIG2 cannot have the same function.
//  6: the bar graph needs low < high inside the span.
bool Ac20Simulator::menu_congruent(int menu) const {
    const int primary = value("primary_variable_selection");
    const bool fahrenheit = value("temperature_input_type") >= 4;
    const std::pair<int, int> span = primary == 0 ? std::pair{0, 200}
                                     : primary == 1 ? (fahrenheit ? std::pair{-100, 100} : std::pair{-75, 40})
                                                    : std::pair{0, 1500};
    auto word = [this](std::string_view name) { return static_cast<std::int16_t>(value(name)); };
    auto ordered = [&](std::string_view low, std::string_view high) { return word(low) < word(high); };
    auto inside = [&](std::string_view low, std::string_view high) {
        return ordered(low, high) && word(low) >= span.first && word(high) <= span.second;
    };
    auto retransmission_ok = [&](int out) {
        const std::string prefix = "out_" + std::to_string(out) + "_";
        const int function = word(prefix + "function");
        return (function != 3 && function != 4) || inside(prefix + "retransmission_low", prefix + "retransmission_high");
    };
    auto display_ok = [&](std::string_view output) {
        const std::string prefix = std::string(output) + "_output_";
        return word(prefix + "scaling") == 0 || ordered(prefix + "display_low", prefix + "display_high");
    };
    const bool manual_available = word("manual_function") == 1;
    switch (menu) {
        case 1: return retransmission_ok(6) && retransmission_ok(7) && inside("bar_graph_low", "bar_graph_high");
        case 2: return retransmission_ok(6) && retransmission_ok(7);
        case 3: return display_ok("main") && display_ok("secondary");
        case 4: return manual_available || word("start_up_status") != 1;
        case 5: {
            const int dig1 = word("dig1_function");
            const int dig2 = word("dig2_function");
            if (dig1 != 0 && dig1 == dig2) return false;
            return manual_available || (dig1 != 3 && dig2 != 3);
        }
        case 6: return inside("bar_graph_low", "bar_graph_high");
        default: return true;
    }
}

// Word 3050: 1 = TB1 European table, 2 = TB2 American table (configuration words only).
void Ac20Simulator::load_configuration_table(int table) {
    for (const auto& [name, raw] : configuration_defaults) store_default(name, raw);
    if (table == 2) {
        for (const auto& [name, raw] : american_differences) store_default(name, raw);
    }
    open_menu_.reset();
    settings_dirty_ = true;
}

void Ac20Simulator::load_control_defaults(int group) {
    for (const auto& [name, raw] : control_defaults(group)) store_default(name, raw);
    settings_dirty_ = true;
}

// Bits 223 and 228: "The command is accepted only if "Smart" (ModBus bit 221) is not active"
// (bit 221 reads tune OR adaptive). Refused with 10, the code for a write the device's state
// does not allow.
std::optional<std::uint8_t> Ac20Simulator::load_default_refusal(const Parameter& parameter, std::uint16_t raw) const {
    if (raw == 0 || (parameter.name != "load_control_defaults" && parameter.name != "load_defaults_group_4")) {
        return std::nullopt;
    }
    const bool smart_active = value("tune_status") != 0 || value("adaptive_status") != 0;
    return smart_active ? std::optional<std::uint8_t>(cannot_modify) : std::nullopt;
}

void Ac20Simulator::after_default_write(const Parameter& parameter, std::uint16_t raw) {
    const std::string& name = parameter.name;
    if (name == "load_configuration_defaults") {
        load_configuration_table(raw);
    } else if (parameter.table == Table::holding_registers && parameter.address >= 3000 && parameter.address <= 3005) {
        open_menu_.reset();  // closed after a passing check
    } else if (auto menu = configuration_menu_of(parameter)) {
        open_menu_ = menu;
    } else if (parameter.table == Table::coils && parameter.address >= 223 && parameter.address <= 232) {
        // Bit 223: every control group except group 7 ("The default value of group 7 (Serial
        // link parameters) are not loaded"); 224-232: group hidden, 1, (2), 3 .. 8.
        if (raw != 0 && parameter.address == 223) {
            for (int group : {0, 1, 3, 4, 5, 6, 8}) load_control_defaults(group);
        } else if (raw != 0) {
            load_control_defaults(parameter.address - 224);
        }
        set_value(name, 0);  // a command, not a state
    }
}

}  // namespace loopwire::device::models
