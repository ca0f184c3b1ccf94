#pragma once
// Files written whole or not at all: a temporary file in the same directory, flushed to disk,
// then renamed over the target, so a crash or a full disk never leaves half a file behind.
#include <string>

#include "common/result.hpp"

namespace loopwire {

Result<void> write_file_atomically(const std::string& path, const std::string& contents);

}  // namespace loopwire
