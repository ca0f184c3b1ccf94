#pragma once
#include <memory>
#include <string>

#include "transport/byte_stream.hpp"

namespace loopwire::transport {

// Baud rates loopwire accepts on serial lines (the three manuals use 600..38400; common USB
// adapters go to 115200).
bool is_supported_baud(std::uint32_t baud);

// Opens a serial device (or pseudo-terminal) raw, with the given settings, exclusively
// (TIOCEXCL, plus flock so a second loopwire gets a clear "busy" error). rs485 = true enables
// kernel RS-485 direction control and fails with a clear message where the driver lacks it.
// Errors say why (missing, busy, permission denied: join the dialout group) and what to try.
Result<std::unique_ptr<ByteStream>> open_serial_port(const std::string& path,
                                                     const SerialSettings& settings);

}  // namespace loopwire::transport
