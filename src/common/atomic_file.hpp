#pragma once
// Files written whole or not at all: a temporary file next to the target, flushed to disk,
// then renamed over it, so a crash or a full disk never leaves half a file behind.
//
// What is at the path decides what "replace" means:
// - nothing: a new file, created with `new_file_mode` less the process umask (the kernel
//   applies it at creation, exactly as for a shell redirection);
// - a regular file: replaced atomically, keeping its permission bits and its owner and group
//   (a file someone made private stays private);
// - a symbolic link (or a chain of them): followed, and its final target replaced atomically,
//   with the temporary file in the target's directory (a rename cannot cross file systems);
//   a dangling link creates its target; the link itself is never replaced;
// - a FIFO or a character device (a pipe, a terminal, /dev/null, /dev/stdout): written into in
//   place, as a shell redirection would, never replaced: `--output /dev/null` or
//   `--output /dev/stdout` does what the user means, and a device node survives. Such a write
//   cannot be atomic, and a FIFO blocks until a reader opens it;
// - a directory, a block device or a socket: refused with an error; never touched.
//
// Temporaries are named `<name>.tmp-XXXXXX` (six letters or digits). A writer killed between
// creating one and renaming it (kill -9, power loss) leaves it behind;
// remove_stale_temporaries() clears those at the next start. One writer per file is assumed.
#include <sys/types.h>

#include <string>
#include <vector>

#include "common/result.hpp"

namespace loopwire {

// For files that may hold secrets (AC20 lock combinations in dumps and simulator state):
// readable and writable by their owner only, whatever the umask allows beyond that.
inline constexpr mode_t private_file_mode = 0600;
// For anything else: what the umask allows, like a shell redirection.
inline constexpr mode_t ordinary_file_mode = 0666;

Result<void> write_file_atomically(const std::string& path, const std::string& contents,
                                   mode_t new_file_mode = ordinary_file_mode);

// Fails (ErrorKind::usage) when write_file_atomically(path, ...) could not succeed now: the
// path (or its link target) is a directory, block device or socket, or no temporary file can be
// created next to it (tried, and removed). For programs that will write later: they can say
// so before they commit to anything.
Result<void> check_writable_atomically(const std::string& path);

// Removes the temporaries write_file_atomically(path) left behind when it was killed, in the
// directory of the path's final target; returns the paths removed. Only regular files owned
// by this user and named exactly like ours are touched.
std::vector<std::string> remove_stale_temporaries(const std::string& path);

}  // namespace loopwire
