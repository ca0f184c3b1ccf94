#include "common/regular_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <system_error>

#include <fmt/format.h>

namespace loopwire {
namespace {

// stat(2)'s file types, as the messages name them.
std::optional<std::string> kind_of(mode_t mode) {
    if (S_ISREG(mode)) return std::nullopt;
    const char* kind = S_ISFIFO(mode)   ? "a FIFO (named pipe)"
                       : S_ISDIR(mode)  ? "a directory"
                       : S_ISCHR(mode)  ? "a character device"
                       : S_ISBLK(mode)  ? "a block device"
                       : S_ISSOCK(mode) ? "a socket"
                                        : "something other than a file";
    return fmt::format("is {}, not a regular file", kind);
}

std::string system_reason(int error) { return std::error_code(error, std::generic_category()).message(); }

Error refused(const std::filesystem::path& path, const std::string& what) {
    return make_error(ErrorKind::usage, fmt::format("\"{}\" {}", path.string(), what));
}

// Closes the descriptor however the read ends.
struct Descriptor {
    int fd = -1;
    ~Descriptor() {
        if (fd >= 0) ::close(fd);
    }
};

}  // namespace

std::optional<std::string> not_a_regular_file(const std::filesystem::path& path) {
    struct stat status {};
    if (::stat(path.c_str(), &status) != 0) {
        return errno == ENOENT ? std::string("does not exist") : fmt::format("cannot be examined ({})", system_reason(errno));
    }
    return kind_of(status.st_mode);
}

Result<std::string> read_regular_file(const std::filesystem::path& path, std::size_t max_size) {
    if (auto what = not_a_regular_file(path)) return refused(path, *what);
    // O_NONBLOCK: should the path have become a FIFO since, open() returns at once; O_NOCTTY:
    // a terminal never becomes this process's controlling one.
    Descriptor file{::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC)};
    if (file.fd < 0) return refused(path, fmt::format("cannot be opened ({})", system_reason(errno)));
    struct stat status {};
    if (::fstat(file.fd, &status) != 0) return refused(path, fmt::format("cannot be examined ({})", system_reason(errno)));
    if (auto what = kind_of(status.st_mode)) return refused(path, *what);
    if (static_cast<std::uintmax_t>(status.st_size) > max_size) {
        return refused(path, fmt::format("is too large: {} bytes (at most {} expected); is it the right file?", status.st_size, max_size));
    }
    std::string text;
    char buffer[4096];
    for (;;) {
        const ssize_t got = ::read(file.fd, buffer, sizeof buffer);
        if (got < 0 && errno == EINTR) continue;
        if (got < 0) return refused(path, fmt::format("cannot be read ({})", system_reason(errno)));
        if (got == 0) break;
        text.append(buffer, static_cast<std::size_t>(got));
        if (text.size() > max_size) {  // it grew while being read
            return refused(path, fmt::format("is too large: over {} bytes; is it the right file?", max_size));
        }
    }
    return text;
}

}  // namespace loopwire
