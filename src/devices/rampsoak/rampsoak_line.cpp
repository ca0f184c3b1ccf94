// How the ramp/soak controller describes its line (§1 Level 3; §7 Register Map rows 0060H-0063H).
// PSL, BITS, IDNO and BAUD are set on the front panel only: the map lists them with function
// code 03H alone, so a write over the line is refused like any read-only register (exception
// 02, profile read_only_writes default), and "When parameter BITS or BAUD was changed, always
// turn on the power again" concerns the panel, not the line.
#include <array>
#include <utility>

#include "devices/rampsoak/rampsoak_simulator.hpp"

namespace loopwire::device::models {
namespace {

// §1 "b R U d": 24, 48, 96, 192, 384 (x100 bps), codes 0-4 in that order (§7 BAUD 0~4).
constexpr std::array<std::pair<std::uint32_t, std::uint16_t>, 5> baud_codes{
    {{2400, 0}, {4800, 1}, {9600, 2}, {19200, 3}, {38400, 4}}};

std::optional<std::uint16_t> baud_code(std::uint32_t baud) {
    for (const auto& [rate, code] : baud_codes) {
        if (rate == baud) return code;
    }
    return std::nullopt;
}

// §1 "b i E S": O B I (odd, 8, 1), O B 2 (odd, 8, 2), E B I (even, 8, 1), E B 2 (even, 8, 2),
// codes 0-3 in that order (§7 BITS 0~3). No parity and 7 data bits are not offered.
std::optional<std::uint16_t> bits_code(const transport::SerialSettings& serial) {
    if (serial.data_bits != 8 || serial.parity == transport::Parity::none) return std::nullopt;
    const int two_stop = serial.stop_bits == 2 ? 1 : 0;
    return static_cast<std::uint16_t>((serial.parity == transport::Parity::odd ? 0 : 2) + two_stop);
}

}  // namespace

// §1 "P S L": P U (MODBUS RTU) 0, P A C I (MODBUS ASCII) 1, P R E (Linking) 2; "I d. N D" the ID
// number the controller answers to (§4.2, §5.2, §6.3). Settings the controller cannot have (no
// parity, 7 data bits, a rate it lacks) leave its word as it was; simulate warns about them.
void RampSoakSimulator::describe_line() {
    const std::string& framing = environment().framing;
    const std::uint16_t protocol = framing == "ascii" ? 1 : framing == "linking" ? 2 : 0;
    set_value("protocol_selection", protocol, Persistence::saved);
    set_value("id_number", environment().unit, Persistence::saved);
    if (!environment().serial) return;
    if (const auto code = baud_code(environment().serial->baud)) set_value("baud_rate", *code, Persistence::saved);
    if (const auto code = bits_code(*environment().serial)) set_value("communication_bits", *code, Persistence::saved);
}

}  // namespace loopwire::device::models
