#include "transport/descriptor_stream.hpp"

#include <poll.h>
#include <unistd.h>

#include <cerrno>

namespace loopwire::transport::detail {

bool is_hang_up(int err) { return err == EIO || err == EPIPE || err == ECONNRESET || err == ENXIO; }

ssize_t DescriptorStream::transmit(ByteView bytes) { return ::write(fd(), bytes.data(), bytes.size()); }

Error DescriptorStream::closed_error(int err) const {
    std::string message = describe() + ": closed by the other side";
    if (err != 0) message += " (" + errno_text(err) + ")";
    return make_error(ErrorKind::link, std::move(message));
}

Result<void> DescriptorStream::wait_writable(Instant stall_deadline) {
    auto ready = wait_for_events(fd(), POLLOUT, stall_deadline);
    if (!ready) return ready.error();
    if (*ready == 0) {
        return make_error(ErrorKind::link,
                          describe() + ": write stalled for " +
                              std::to_string(write_stall_limit.count()) +
                              " s — the other side is not reading");
    }
    // POLLERR/POLLHUP: the next transmit() reports the reason.
    return {};
}

Result<void> DescriptorStream::write(ByteView bytes) {
    if (auto handed = hand_over(bytes); !handed) return handed;
    return after_write();
}

Result<void> DescriptorStream::write_now(ByteView bytes) {
    if (auto handed = hand_over(bytes, WhenFull::fail); !handed) return handed;
    return after_write();
}

Result<void> DescriptorStream::hand_over(ByteView bytes, WhenFull when_full) {
    std::size_t sent = 0;
    while (sent < bytes.size()) {
        const ssize_t n = transmit(bytes.subspan(sent));
        if (n > 0) {
            sent += static_cast<std::size_t>(n);
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            if (when_full == WhenFull::fail) {
                return make_error(ErrorKind::link, describe() + ": the other side is not reading (the kernel's send buffer is full, " +
                                                       std::to_string(sent) + " of " + std::to_string(bytes.size()) +
                                                       " bytes taken); not waited for");
            }
            // The kernel buffer is full: wait for room, but not forever.
            auto room = wait_writable(std::chrono::steady_clock::now() + write_stall_limit);
            if (!room) return room;
            continue;
        }
        const int err = n < 0 ? errno : EIO;
        if (is_hang_up(err)) return closed_error(err);
        return make_error(ErrorKind::link, describe() + ": write failed: " + errno_text(err));
    }
    return {};
}

// One read after poll() reported activity. `retry` is set when nothing was there after all
// (another reader was faster, or a spurious wake-up) so the caller waits again.
Result<std::size_t> DescriptorStream::receive_ready(std::span<std::uint8_t> buffer, bool& retry) {
    retry = false;
    const ssize_t n = ::read(fd(), buffer.data(), buffer.size());
    if (n > 0) return static_cast<std::size_t>(n);
    // Descriptors are non-blocking, so 0 is end-of-file (or a terminal hang-up), not "no data".
    if (n == 0) return closed_error(0);
    if (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK) {
        retry = true;
        return std::size_t{0};
    }
    if (is_hang_up(errno)) return closed_error(errno);
    return make_error(ErrorKind::link, describe() + ": read failed: " + errno_text(errno));
}

Result<std::size_t> DescriptorStream::read_some(std::span<std::uint8_t> buffer, milliseconds timeout) {
    if (buffer.empty()) return std::size_t{0};
    // Bytes already waiting on a socket (the usual case for a server woken by its own poll)
    // cost one read() and no poll().
    if (reads_without_waiting()) {
        bool retry = false;
        auto got = receive_ready(buffer, retry);
        if (!retry) return got;
    }
    const Instant deadline = deadline_after(timeout);
    for (;;) {
        auto ready = wait_for_events(fd(), POLLIN, deadline);
        if (!ready) return ready.error();
        if (*ready == 0) return std::size_t{0};
        if (*ready & POLLNVAL) {
            return make_error(ErrorKind::link, describe() + ": descriptor is not open");
        }
        bool retry = false;
        auto got = receive_ready(buffer, retry);
        if (!retry) return got;
    }
}

void DescriptorStream::discard_input() {
    std::uint8_t scratch[512];
    // Bounded so a peer that sends without pause cannot keep us here forever.
    for (int round = 0; round < 64; ++round) {
        const ssize_t n = ::read(fd(), scratch, sizeof scratch);
        if (n <= 0 && !(n < 0 && errno == EINTR)) return;
    }
}

}  // namespace loopwire::transport::detail
