#include "transport/pseudo_terminal.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdlib>

#include "transport/descriptor_stream.hpp"
#include "transport/serial_settings.hpp"

namespace loopwire::transport {

using detail::FileDescriptor;

namespace {

Error pty_error(const std::string& link_path, const std::string& step, int err) {
    return make_error(ErrorKind::link, "pseudo-terminal for " + link_path + ": " + step +
                                           " failed: " + detail::errno_text(err));
}

// The symlink is ours while it still points at our slave device; never remove a link that
// someone replaced in the meantime.
void remove_own_symlink(const std::string& link_path, const std::string& slave_path) {
    char target[PATH_MAX];
    const ssize_t n = ::readlink(link_path.c_str(), target, sizeof target - 1);
    if (n < 0 || std::string(target, static_cast<std::size_t>(n)) != slave_path) return;
    ::unlink(link_path.c_str());
}

class PseudoTerminalStream final : public detail::DescriptorStream {
public:
    PseudoTerminalStream(FileDescriptor master, FileDescriptor slave, std::string link_path,
                         std::string slave_path)
        : DescriptorStream(std::move(master), "pty " + link_path + " -> " + slave_path),
          slave_(std::move(slave)),
          link_path_(std::move(link_path)),
          slave_path_(std::move(slave_path)) {}

    ~PseudoTerminalStream() override { remove_own_symlink(link_path_, slave_path_); }

    // Drops what the client wrote and we have not read yet.
    void discard_input() override { ::tcflush(fd(), TCIFLUSH); }

private:
    // Held open for the stream's whole life: clients open and close the link per run, and when
    // the last slave descriptor closes the master reads EIO and reports POLLHUP until someone
    // opens it again. Never read from: the client's descriptor gets the bytes we write.
    FileDescriptor slave_;
    std::string link_path_;
    std::string slave_path_;
};

struct PseudoTerminalPair {
    FileDescriptor master;
    FileDescriptor slave;
    std::string slave_path;
};

Result<PseudoTerminalPair> open_pair(const std::string& link_path) {
    PseudoTerminalPair pair;
    pair.master = FileDescriptor(::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC));
    if (!pair.master.valid()) return pty_error(link_path, "posix_openpt", errno);
    const int master = pair.master.get();
    if (::grantpt(master) != 0) return pty_error(link_path, "grantpt", errno);
    if (::unlockpt(master) != 0) return pty_error(link_path, "unlockpt", errno);
    char name[PATH_MAX];
    if (const int err = ::ptsname_r(master, name, sizeof name); err != 0) {
        return pty_error(link_path, "ptsname", err);
    }
    pair.slave_path = name;
    pair.slave = FileDescriptor(::open(name, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
    if (!pair.slave.valid()) return pty_error(link_path, "opening " + pair.slave_path, errno);
    if (auto ok = detail::make_non_blocking(master); !ok) return ok.error();
    return pair;
}

const char* file_kind(mode_t mode) {
    if (S_ISREG(mode)) return "a regular file";
    if (S_ISDIR(mode)) return "a directory";
    if (S_ISCHR(mode)) return "a character device";
    return "not a symlink";
}

// Replaces a stale symlink (left by a crashed run, or another pseudo-terminal), but nothing
// else: a regular file or device at that path is somebody's data.
Result<void> place_symlink(const std::string& link_path, const std::string& target) {
    struct stat existing {};
    if (::lstat(link_path.c_str(), &existing) == 0) {
        if (!S_ISLNK(existing.st_mode)) {
            return make_error(ErrorKind::usage, "refusing to replace " + link_path + ": it is " +
                                                    file_kind(existing.st_mode) +
                                                    ", not a symlink — choose another link path");
        }
        if (::unlink(link_path.c_str()) != 0 && errno != ENOENT) {
            return pty_error(link_path, "removing the old symlink", errno);
        }
    } else if (errno != ENOENT) {
        return pty_error(link_path, "checking the link path", errno);
    }
    if (::symlink(target.c_str(), link_path.c_str()) != 0) {
        if (errno == ENOENT) {
            return make_error(ErrorKind::usage, "cannot create " + link_path +
                                                    ": its directory does not exist");
        }
        return pty_error(link_path, "creating the symlink", errno);
    }
    return {};
}

}  // namespace

Result<std::unique_ptr<ByteStream>> create_pseudo_terminal(const std::string& link_path,
                                                           const SerialSettings& settings) {
    if (link_path.empty()) return make_error(ErrorKind::usage, "pseudo-terminal: empty link path");
    auto pair = open_pair(link_path);
    if (!pair) return pair.error();
    // Settings live on the slave side, which is the terminal clients see.
    const std::string what = "pseudo-terminal " + pair->slave_path;
    if (auto ok = detail::apply_serial_settings(pair->slave.get(), settings, what); !ok) return ok.error();
    if (auto ok = detail::apply_rs485(pair->slave.get(), settings, what); !ok) return ok.error();
    if (auto ok = place_symlink(link_path, pair->slave_path); !ok) return ok.error();
    return std::unique_ptr<ByteStream>(std::make_unique<PseudoTerminalStream>(
        std::move(pair->master), std::move(pair->slave), link_path, pair->slave_path));
}

}  // namespace loopwire::transport
