#pragma once
// One string names a link everywhere (docs/DESIGN.md, "Links"):
//   rtu:/dev/ttyUSB0?baud=19200&parity=even&stop=1&data=8&rs485=1
//   rtu:/dev/ttyUSB0?baud=19200&rs485=auto&rs485_delay_before=1ms&guard=5ms
//   ascii:/dev/ttyS1?baud=9600&parity=even&data=7
//   linking:/dev/ttyS1?baud=9600
//   tcp://127.0.0.1:502
//   rtu+tcp://serial-server.local:4001
//   rtu:virtual            (an in-process virtual bus, for demos and tests)
#include <cstdint>
#include <string>
#include <string_view>

#include "common/result.hpp"
#include "transport/byte_stream.hpp"

namespace loopwire::transport {

enum class Framing { rtu, ascii, linking, tcp, rtu_over_tcp };
std::string framing_name(Framing framing);  // "rtu", "ascii", "linking", "tcp", "rtu+tcp"

struct LinkUrl {
    Framing framing = Framing::rtu;
    std::string path;        // serial device path (serial framings)
    std::string host;        // tcp framings
    std::uint16_t port = 0;  // tcp framings
    SerialSettings serial;   // serial framings; defaults 19200 8E1 (Modbus serial-line default)

    bool is_serial() const { return framing != Framing::tcp && framing != Framing::rtu_over_tcp; }
    std::string to_string() const;
};

// Errors are ErrorKind::usage and name the bad part: "link URL 'rtu:/dev/x?baud=12345': baud
// 12345 is not a supported rate (600, 1200, ... 115200)".
Result<LinkUrl> parse_link_url(std::string_view text);

// The serial line options a link URL and a gateway's [[lines]] table share. Errors are
// ErrorKind::usage naming the option ("rs485 'yes' is not valid ..."), for the caller to place.
// rs485: 1, true or on; 0, false or off; auto (on where the driver supports it).
Result<Rs485> parse_rs485(std::string_view text);
// rs485_delay_before / _after: a duration of whole milliseconds, 0 to 1s (the kernel's limit
// for most drivers is lower: it caps what it cannot keep).
Result<milliseconds> parse_rs485_delay(std::string_view text, std::string_view option);
// guard: "3.5c" (characters at the line's speed, up to 1000) or a duration up to 1s.
Result<LineGuard> parse_line_guard(std::string_view text);
std::string rs485_text(Rs485 rs485);        // "0", "1", "auto"
std::string line_guard_text(LineGuard guard);  // "3.5c", "5ms", "250us"

}  // namespace loopwire::transport
