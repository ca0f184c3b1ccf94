#include "app/atomic_file.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>

namespace loopwire::app {
namespace {

Error file_error(const std::string& path, const char* action) {
    return Error{ErrorKind::usage, fmt::format("cannot {} {}: {}; check the directory exists and is writable", action,
                                               path, std::strerror(errno))};
}

bool write_all(int fd, const std::string& contents) {
    std::size_t done = 0;
    while (done < contents.size()) {
        const ssize_t n = ::write(fd, contents.data() + done, contents.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return false;
        done += static_cast<std::size_t>(n);
    }
    return true;
}

}  // namespace

Result<void> write_file_atomically(const std::string& path, const std::string& contents) {
    std::string temporary = path + ".XXXXXX";
    const int fd = ::mkstemp(temporary.data());
    if (fd < 0) return file_error(path, "create a temporary file beside");
    const bool written = write_all(fd, contents) && ::fsync(fd) == 0;
    const int saved_errno = errno;
    ::close(fd);
    if (!written) {
        ::unlink(temporary.c_str());
        errno = saved_errno;
        return file_error(path, "write");
    }
    // mkstemp makes the file 0600; a state or dump file is an ordinary user file.
    ::chmod(temporary.c_str(), 0644);
    if (std::rename(temporary.c_str(), path.c_str()) != 0) {
        const Error error = file_error(path, "replace");
        ::unlink(temporary.c_str());
        return error;
    }
    return {};
}

}  // namespace loopwire::app
