// How the AC20 describes its line: words 526-529, menu group 7 "Sr.Ln" (S.L.Pr, S.L.Ad, S.L.bd,
// S.L.bF). Each says "The new data will be activated after the device answer": a write is
// answered as the device was, and from the next request on the device answers at its new
// address, and hears nothing on a line whose rate or byte format it no longer has.
#include <array>
#include <utility>

#include "devices/ac20/ac20_simulator.hpp"

namespace loopwire::device::models {
namespace {

// Word 528: 0 = 600 Baud ... 5 = 19200 Baud.
constexpr std::array<std::pair<std::uint32_t, std::uint16_t>, 6> baud_codes{
    {{600, 0}, {1200, 1}, {2400, 2}, {4800, 3}, {9600, 4}, {19200, 5}}};

std::optional<std::uint16_t> baud_code(std::uint32_t baud) {
    for (const auto& [rate, code] : baud_codes) {
        if (rate == baud) return code;
    }
    return std::nullopt;
}

// Word 529: 0 = 8 bits + even parity, 1 = 8 bits + odd parity, 2 = 8 bits without parity
// ("Transmission format": 1 start, 8 data, optional parity, 1 stop).
std::optional<std::uint16_t> format_code(const transport::SerialSettings& serial) {
    if (serial.data_bits != 8 || serial.stop_bits != 1) return std::nullopt;
    switch (serial.parity) {
        case transport::Parity::even: return 0;
        case transport::Parity::odd: return 1;
        case transport::Parity::none: return 2;
    }
    return std::nullopt;
}

constexpr std::uint16_t protocol_none = 0;    // word 526: 0 = No serial interface
constexpr std::uint16_t protocol_modbus = 1;  // 1 = Modbus (2 = Jbus keeps its numbering)

}  // namespace

// The device is served as unit N on this line, so it is set up that way: its address N, the
// line's rate and byte format, and a serial interface (Modbus unless it was set to Jbus).
// Settings the AC20 cannot have (38400 baud, 7 data bits, 2 stop bits) leave their word as it
// was; simulate warns about them.
void Ac20Simulator::describe_line() {
    set_value("serial_link_address", environment().unit, Persistence::saved);
    if (value("serial_interface_protocol") == protocol_none) {
        set_value("serial_interface_protocol", protocol_modbus, Persistence::saved);
    }
    if (environment().serial) {
        if (const auto code = baud_code(environment().serial->baud)) set_value("serial_baud_rate", *code, Persistence::saved);
        if (const auto code = format_code(*environment().serial)) set_value("serial_byte_format", *code, Persistence::saved);
    }
    answer_as(std::nullopt);
}

// Where the words now put the device: off the line (0) when its serial interface is off or its
// rate or byte format differs from the line's, else at its address.
void Ac20Simulator::follow_line_words() {
    const auto& serial = environment().serial;
    const bool off = value("serial_interface_protocol") == protocol_none;
    const auto line_baud = serial ? baud_code(serial->baud) : std::nullopt;
    const auto line_format = serial ? format_code(*serial) : std::nullopt;
    const bool other_rate = line_baud && value("serial_baud_rate") != *line_baud;
    const bool other_format = line_format && value("serial_byte_format") != *line_format;
    if (off || other_rate || other_format) {
        answer_as(std::uint8_t{0});
        return;
    }
    const std::uint16_t address = value("serial_link_address");
    if (address == environment().unit || address == 0 || address > 255) answer_as(std::nullopt);
    else answer_as(static_cast<std::uint8_t>(address));
}

// After any write, not only to 526-529: bit 231 loads group 7's defaults (19200 baud, 8E1,
// Modbus), which move the device off a line at other settings just the same.
void Ac20Simulator::after_line_write() { follow_line_words(); }

}  // namespace loopwire::device::models
