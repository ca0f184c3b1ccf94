// Tc10Simulator: rules that tie words together, beyond the ranges the profile checks for every
// write (tc10-modbus-im05c01e81-03.ru.txt §5.1 22A–25A, §5.3.1 #2, §5.3 bounds named by other
// parameters). A refused write answers exception 3 and changes nothing (§4.4 B.2).
#include <algorithm>
#include <array>

#include "devices/tc10/tc10_simulator.hpp"

namespace loopwire::device::models {
namespace {

constexpr std::uint8_t illegal_data_value = 3;

// §5.1 22A/23A: "10000 = Временное значение не вставлено" (temporary value not entered);
// §5.1 24A/25A: "-1 = Код не запрограммирован" (code not programmed).
constexpr std::uint16_t not_entered = 10000;
constexpr std::uint16_t not_programmed = 0xFFFF;  // -1

// §5.3.1 #1 SEnS: codes 9…16 (0.60 … 2.10, mV / mA / V) are the linear inputs; 0…8 are
// thermocouples, infrared sensors and RTDs.
constexpr std::uint16_t first_linear_input = 9;
constexpr std::uint16_t last_listed_input = 16;

// §5.3.12 (CAI) #139 A.L.P "-1999 ... (A.H.P - 10)", #141 A.H.P "(A.L.P + 10) ... 9999": the
// points stay 10 apart, in display counts like the rest of the column.
constexpr int calibration_gap = 10;

int signed_word(std::uint16_t raw) { return static_cast<std::int16_t>(raw); }

bool linear_input(std::uint16_t input_type) { return input_type >= first_linear_input && input_type <= last_listed_input; }

// §5.3.1 #2 dP: "Позиция десятичной точки (линейные входы) 0 ... 3" / "(входы, отличные от
// линейных) 0/1" — 0…3 decimals for linear inputs, 0 or 1 for the others.
std::uint16_t decimal_point_limit(std::uint16_t input_type) { return linear_input(input_type) ? 3 : 1; }

// §5.1 22A: "AA ВВ, где: AA = Тип входа: 0 ... 25, ВВ = Тип управления и служебные функции:
// 0 ... 21" — two decimal digits each (AA = input type, BB = control type and services).
bool valid_first_code(std::uint16_t raw) {
    const int code = signed_word(raw);
    return code >= 0 && code / 100 <= 25 && code % 100 <= 21;
}

// §5.1 23A: "CDEF, где: C = Тип сигнализации 1: 0 ... 9, D = Тип сигнализации 2: 0 ... 9,
// E = Тип сигнализации 3: 0 ... 9, F = Включение служебных функций: 0 ... 4".
bool valid_second_code(std::uint16_t raw) {
    const int code = signed_word(raw);
    return code >= 0 && code <= 9999 && code % 10 <= 4;
}

}  // namespace

void Tc10Simulator::apply_code_defaults() {
    set_value("quick_config_temp_code_1", not_entered, Persistence::saved);
    set_value("quick_config_temp_code_2", not_entered, Persistence::saved);
    set_value("quick_config_final_code_1", not_programmed, Persistence::saved);
    set_value("quick_config_final_code_2", not_programmed, Persistence::saved);
}

std::uint16_t Tc10Simulator::current(std::string_view name) const {
    if (const auto staged = staged_.find(name); staged != staged_.end()) return staged->second;
    return value(name);
}

std::optional<std::uint8_t> Tc10Simulator::check_rules(const Parameter& parameter, std::uint16_t raw) {
    const std::string_view name = parameter.name;
    // §5.3.1 #2: a dP the current input type does not offer is out of range (§4.4 B.2). The
    // input type may be written earlier in the same request.
    if (name == "decimal_point" && raw > decimal_point_limit(current("input_type"))) return illegal_data_value;
    // §5.1 22A/23A: each digit group within its printed range; 10000 (not entered) clears.
    if (name == "quick_config_temp_code_1" && raw != not_entered && !valid_first_code(raw)) return illegal_data_value;
    if (name == "quick_config_temp_code_2" && raw != not_entered && !valid_second_code(raw)) return illegal_data_value;
    // §5.3.12 (CAI) #139 / #141: "-1999 ... (A.H.P - 10)", "(A.L.P + 10) ... 9999".
    if (name == "calibration_low_point" &&
        signed_word(raw) > signed_word(current("calibration_high_point")) - calibration_gap) {
        return illegal_data_value;
    }
    if (name == "calibration_high_point" &&
        signed_word(raw) < signed_word(current("calibration_low_point")) + calibration_gap) {
        return illegal_data_value;
    }
    staged_[parameter.name] = raw;
    return std::nullopt;
}

void Tc10Simulator::after_rule_write(const Parameter& parameter) {
    const std::string_view name = parameter.name;
    if (name == "input_type") limit_decimal_point();
    if (name == "quick_config_temp_code_1" || name == "quick_config_temp_code_2") apply_quick_configuration();
    follow_limits(parameter);
}

// §5.3.1 #2 leaves open what becomes of dP 2 or 3 when SEnS changes to a non-linear input. The
// simulator's choice: the SEnS write is accepted (it is in range) and dP drops to 1, the
// largest the new input offers; every dP value keeps its raw count, now read with 1 decimal.
void Tc10Simulator::limit_decimal_point() {
    const std::uint16_t limit = decimal_point_limit(value("input_type"));
    if (value("decimal_point") > limit) set_value("decimal_point", limit, Persistence::saved);
}

// §5.1 22A/23A: "Запрограммированные коды будут активированы только после правильного задания
// обеих субкодов. Порядок не имеет значения." — the codes take effect only once both have been
// entered correctly, in either order. Then: the final codes (24A/25A) read them, the temporary
// words read 10000 again, and the settings the manual decodes are applied: AA → SEnS (#1) where
// AA is one of its listed codes (0…16; 17…25 are in 22A's range but §5.3.1 lists no such input,
// so SEnS stays), C/D/E → AL1t/AL2t/AL3t (#28, #36, #44, same 0…9 codes). BB (control type and
// services) and F (services) are recorded in the final codes only: the manual lists no meanings.
void Tc10Simulator::apply_quick_configuration() {
    const std::uint16_t first = value("quick_config_temp_code_1");
    const std::uint16_t second = value("quick_config_temp_code_2");
    if (first == not_entered || second == not_entered) return;
    set_value("quick_config_final_code_1", first, Persistence::saved);
    set_value("quick_config_final_code_2", second, Persistence::saved);
    set_value("quick_config_temp_code_1", not_entered, Persistence::saved);
    set_value("quick_config_temp_code_2", not_entered, Persistence::saved);
    const auto input = static_cast<std::uint16_t>(first / 100);
    if (input <= last_listed_input) set_value("input_type", input, Persistence::saved);
    limit_decimal_point();
    const std::array<std::string_view, 3> alarm_types{"alarm_1_type", "alarm_2_type", "alarm_3_type"};
    const std::array<std::uint16_t, 3> digits{static_cast<std::uint16_t>(second / 1000),
                                              static_cast<std::uint16_t>(second / 100 % 10),
                                              static_cast<std::uint16_t>(second / 10 % 10)};
    for (std::size_t i = 0; i < alarm_types.size(); ++i) set_value(alarm_types[i], digits[i], Persistence::saved);
}

// §5.3 prints ranges that name other parameters ("SP.LL ... SP.HL" for SP…SP 4 and 6A–9A, 16A;
// "AL1L ... AL1H" for AL1; "Ao1L ... Ao1H" for 29A). The manual does not say what happens to a
// value when its limit is moved past it; the simulator's choice: the value is brought to the new
// limit, so every such range holds at all times, not only at the value's own writes.
void Tc10Simulator::follow_limits(const Parameter& limit) {
    for (const Parameter& bounded : profile().parameters) {
        const auto names = [&](const std::optional<Bound>& bound) {
            const std::string* name = bound ? std::get_if<std::string>(&*bound) : nullptr;
            return name != nullptr && *name == limit.name;
        };
        const bool below = names(bounded.min);
        const bool above = names(bounded.max);
        if (!below && !above) continue;
        const int stored = signed_word(value(bounded.name));
        const int bound = signed_word(value(limit.name));
        if ((below && stored < bound) || (above && stored > bound)) {
            set_value(bounded.name, value(limit.name), Persistence::saved);
        }
    }
}

}  // namespace loopwire::device::models
