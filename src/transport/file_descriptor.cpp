#include "transport/file_descriptor.hpp"

#include <fcntl.h>
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <system_error>

namespace loopwire::transport::detail {

void FileDescriptor::reset(int fd) {
    // close() is not retried on EINTR: on Linux the descriptor is released either way.
    if (fd_ >= 0) ::close(fd_);
    fd_ = fd;
}

std::string errno_text(int err) { return std::error_code(err, std::generic_category()).message(); }

Instant deadline_after(std::chrono::milliseconds timeout) {
    // Callers pass milliseconds::max() to mean "no limit"; adding that to now() would overflow.
    constexpr std::chrono::milliseconds longest = std::chrono::hours(24 * 365);
    return std::chrono::steady_clock::now() + std::clamp(timeout, std::chrono::milliseconds{0}, longest);
}

namespace {

// poll() counts whole milliseconds; rounding up keeps us from reporting a timeout early.
int poll_timeout_until(Instant deadline) {
    const auto remaining = deadline - std::chrono::steady_clock::now();
    if (remaining <= remaining.zero()) return 0;
    const auto ms = std::chrono::ceil<std::chrono::milliseconds>(remaining).count();
    return ms > INT_MAX ? INT_MAX : static_cast<int>(ms);
}

}  // namespace

Result<short> wait_for_events(int fd, short events, Instant deadline) {
    for (;;) {
        pollfd entry{fd, events, 0};
        const int ready = ::poll(&entry, 1, poll_timeout_until(deadline));
        if (ready > 0) return entry.revents;
        if (ready < 0 && errno != EINTR) {
            return make_error(ErrorKind::link, "poll() failed: " + errno_text(errno));
        }
        if (ready == 0 && std::chrono::steady_clock::now() >= deadline) return short{0};
    }
}

Result<void> make_non_blocking(int fd) {
    const int flags = ::fcntl(fd, F_GETFL);
    if (flags < 0 || ::fcntl(fd, F_SETFL, flags | O_NONBLOCK) < 0) {
        return make_error(ErrorKind::link, "cannot make descriptor non-blocking: " + errno_text(errno));
    }
    return {};
}

}  // namespace loopwire::transport::detail
