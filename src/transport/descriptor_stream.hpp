#pragma once
// Internal to the transport layer: the ByteStream behaviour every file-descriptor transport
// shares (serial port, pseudo-terminal master, TCP connection). Each kind adds what differs:
// how bytes leave, what "closed" means, how input is discarded.
#include <chrono>
#include <string>
#include <sys/types.h>

#include "transport/byte_stream.hpp"
#include "transport/file_descriptor.hpp"

namespace loopwire::transport::detail {

class DescriptorStream : public ByteStream {
public:
    Result<void> write(ByteView bytes) override;
    Result<void> write_now(ByteView bytes) override;
    Result<std::size_t> read_some(std::span<std::uint8_t> buffer, milliseconds timeout) override;
    // Reads and drops whatever is waiting (sockets); terminals override this with tcflush.
    void discard_input() override;
    int poll_handle() const override { return fd_.get(); }
    std::string describe() const override { return description_; }

    // A write that makes no progress this long fails instead of hanging its caller: the other
    // side stopped reading (a pseudo-terminal nobody has open, a stalled TCP peer). Generous
    // enough for a full 4 KiB UART buffer to make room at 600 baud.
    static constexpr std::chrono::seconds write_stall_limit{10};

protected:
    // `fd` must be non-blocking.
    DescriptorStream(FileDescriptor fd, std::string description)
        : fd_(std::move(fd)), description_(std::move(description)) {}

    int fd() const { return fd_.get(); }

    // Hands bytes to the kernel once, with ::write() semantics (-1 and errno on failure).
    virtual ssize_t transmit(ByteView bytes);
    // Hands every byte to the kernel, waiting for room when its buffer is full (not for the
    // bytes to leave: after_write is what waits for that); or, not to wait, failing then.
    enum class WhenFull { wait, fail };
    Result<void> hand_over(ByteView bytes, WhenFull when_full = WhenFull::wait);
    // Runs once the kernel accepted every byte; serial ports wait there until the UART sent
    // them, so the caller's clock starts when the frame is really on the wire.
    virtual Result<void> after_write() { return {}; }
    // The error for end-of-file (err = 0) or a hang-up / reset reported as errno `err`.
    virtual Error closed_error(int err) const;
    // Whether a read with nothing waiting says so with EAGAIN, so read_some may try read()
    // before poll(). Sockets do; raw terminals (VMIN = VTIME = 0) return 0, which would look
    // like end-of-file, so they poll first.
    virtual bool reads_without_waiting() const { return false; }

private:
    Result<void> wait_writable(Instant stall_deadline);
    Result<std::size_t> receive_ready(std::span<std::uint8_t> buffer, bool& retry);

    FileDescriptor fd_;
    std::string description_;
};

// errno values that mean the other side is gone rather than a local fault.
bool is_hang_up(int err);

}  // namespace loopwire::transport::detail
