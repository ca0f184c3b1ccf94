#pragma once
#include <memory>
#include <string>

#include "transport/byte_stream.hpp"

namespace loopwire::transport {

// The controlling side of a new pseudo-terminal, with a symlink at `link_path` to its slave
// device, so any program (mbpoll, pymodbus, a SCADA driver) can open `link_path` like a serial
// port. The symlink is removed when the stream is destroyed. Refuses to replace an existing
// file that is not a symlink.
Result<std::unique_ptr<ByteStream>> create_pseudo_terminal(const std::string& link_path,
                                                           const SerialSettings& settings);

}  // namespace loopwire::transport
