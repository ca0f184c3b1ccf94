#pragma once
// Internal to the transport layer: serial settings → termios, shared by serial ports and
// pseudo-terminals, and the list of rates the link URL parser checks against.
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include "transport/byte_stream.hpp"

namespace loopwire::transport::detail {

// Every rate loopwire accepts, ascending.
std::span<const std::uint32_t> supported_bauds();
// "600, 1200, 2400, ... 115200": for error messages.
std::string supported_bauds_text();

// "19200 8E1": how people write a character format.
std::string settings_text(const SerialSettings& settings);

// Usage error unless baud, data bits (7, 8) and stop bits (1, 2) are ones loopwire supports.
Result<void> check_settings(const SerialSettings& settings, const std::string& what);

// Raw mode (no echo, no line editing, no flow control, no character translation) with the
// given speed and character format; reads never block in the driver (VMIN = VTIME = 0), the
// streams wait in poll() instead. `what` names the device in error messages.
Result<void> apply_serial_settings(int fd, const SerialSettings& settings, const std::string& what);

// As settings.rs485 says, asks the driver to switch the RS-485 transmitter on while sending (RTS
// high during the frame, with the settings' delays). A driver without it fails Rs485::on with a
// link error that says what to do; Rs485::if_supported runs on and warns on stderr, once per
// open. Rs485::off does nothing.
Result<void> apply_rs485(int fd, const SerialSettings& settings, const std::string& what);

// Whether the driver of the port at `path` has kernel RS-485 direction control, asked without
// changing it (TIOCGRS485 on the port opened without becoming its controlling terminal, closed at
// once): nullopt when it has, or when the port cannot be opened now (the line's own open says
// why); otherwise the refusal's text.
std::optional<std::string> rs485_unsupported(const std::string& path);

}  // namespace loopwire::transport::detail
