#pragma once
// Files a user names for reading (a configuration, a password, a certificate, a profile) must be
// regular files, and that is found out before they are opened: opening a FIFO for reading
// blocks until something writes to it (a `--check` that never ends, a reload that wedges the
// thread that also handles SIGTERM), and opening a serial device may reset whatever hangs on
// it (DTR). The file is then opened without blocking and checked again on the descriptor, so a
// file swapped for a FIFO between the two cannot block the reader either.
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>

#include "common/result.hpp"

namespace loopwire {

// What `path` is when it is not a regular file, found with stat() (symbolic links followed),
// never by opening it: "does not exist", "is a FIFO (named pipe), not a regular file" (likewise
// a directory, a character or block device, a socket), or "cannot be examined (REASON)".
// nullopt: a regular file.
std::optional<std::string> not_a_regular_file(const std::filesystem::path& path);

// The whole text of the regular file at `path`, of at most `max_size` bytes. Errors
// (ErrorKind::usage) begin with the quoted path and say what it is instead ("\"/x\" is a FIFO
// (named pipe), not a regular file"); callers add which setting named it and what to do.
Result<std::string> read_regular_file(const std::filesystem::path& path, std::size_t max_size);

}  // namespace loopwire
