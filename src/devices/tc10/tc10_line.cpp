// How the TC10 describes its line: §5.3.11 (Ser) #131 Add (769) and #132 bAud (770); the byte
// format is fixed at 8 bits, no parity, 1 stop bit (§1, §3), so no word holds it.
#include <array>
#include <utility>

#include "devices/tc10/tc10_simulator.hpp"

namespace loopwire::device::models {
namespace {

// #132 bAud: 0 = 1200, 1 = 2400, 2 = 9600, 3 = 19.2 (19200), 4 = 38.4 (38400) бод.
constexpr std::array<std::pair<std::uint32_t, std::uint16_t>, 5> baud_codes{
    {{1200, 0}, {2400, 1}, {9600, 2}, {19200, 3}, {38400, 4}}};

std::optional<std::uint16_t> baud_code(std::uint32_t baud) {
    for (const auto& [rate, code] : baud_codes) {
        if (rate == baud) return code;
    }
    return std::nullopt;
}

}  // namespace

// Served as unit N at some rate: Add = N, bAud = that rate (one the TC10 lacks, e.g. 4800,
// leaves bAud as it was; simulate warns about the link).
//
// After construction describe_line runs only when saved contents are reloaded (--state), i.e.
// the controller is powered up again after having been powered off: §5.1 10A bit 10
// "Индикатор сбоя питания" (power failure indicator) is then on, until an alarm reset (word 13).
// A simulator started without saved contents is a controller's first power-up: no indication.
void Tc10Simulator::describe_line() {
    if (constructed_) power_failed_ = true;
    set_value("device_address", environment().unit, Persistence::saved);
    if (environment().serial) {
        if (const auto code = baud_code(environment().serial->baud)) set_value("baud_rate", *code, Persistence::saved);
    }
    answer_as(std::nullopt);
}

// The manual does not say when a new Add or bAud takes effect (profiles/NOTES.md): as on the
// AC20, after the reply to the write. Add = 0 is "oFF" (#131: serial communication off): the
// device then hears nothing; so does one set to a rate other than the line's.
void Tc10Simulator::follow_line_words() {
    const auto& serial = environment().serial;
    const auto line_baud = serial ? baud_code(serial->baud) : std::nullopt;
    const std::uint16_t address = value("device_address");
    if (address == 0 || (line_baud && value("baud_rate") != *line_baud)) {
        answer_as(std::uint8_t{0});
    } else if (address == environment().unit || address > 255) {
        answer_as(std::nullopt);
    } else {
        answer_as(static_cast<std::uint8_t>(address));
    }
}

void Tc10Simulator::after_line_write(const Parameter& parameter) {
    if (parameter.name == "device_address" || parameter.name == "baud_rate") follow_line_words();
}

}  // namespace loopwire::device::models
