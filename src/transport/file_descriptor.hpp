#pragma once
// Internal to the transport layer: an owning file descriptor and poll() with a deadline, shared
// by the serial port, pseudo-terminal and TCP streams.
#include <chrono>
#include <string>

#include "common/bytes.hpp"
#include "common/result.hpp"

namespace loopwire::transport::detail {

class FileDescriptor {
public:
    FileDescriptor() = default;
    explicit FileDescriptor(int fd) : fd_(fd) {}
    ~FileDescriptor() { reset(); }
    FileDescriptor(FileDescriptor&& other) noexcept : fd_(other.release()) {}
    FileDescriptor& operator=(FileDescriptor&& other) noexcept {
        if (this != &other) reset(other.release());
        return *this;
    }
    FileDescriptor(const FileDescriptor&) = delete;
    FileDescriptor& operator=(const FileDescriptor&) = delete;

    int get() const { return fd_; }
    bool valid() const { return fd_ >= 0; }
    int release() {
        const int fd = fd_;
        fd_ = -1;
        return fd;
    }
    void reset(int fd = -1);

private:
    int fd_ = -1;
};

// The system's text for an errno value ("No such file or directory"), thread-safe.
std::string errno_text(int err);

// `timeout` from now; negative timeouts count as zero, absurdly long ones as a year.
Instant deadline_after(std::chrono::milliseconds timeout);

// Waits with poll() until `fd` reports one of `events` or `deadline` passes, resuming after
// signals. Returns the reported events, or 0 once the deadline has passed (never earlier).
Result<short> wait_for_events(int fd, short events, Instant deadline);

// Sets O_NONBLOCK: every stream does its waiting in poll(), so a read or write never blocks
// past the caller's timeout.
Result<void> make_non_blocking(int fd);

}  // namespace loopwire::transport::detail
