#include "transport/serial_port.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>

#include "transport/descriptor_stream.hpp"
#include "transport/serial_settings.hpp"

namespace loopwire::transport {

using detail::FileDescriptor;

bool is_supported_baud(std::uint32_t baud) {
    const auto bauds = detail::supported_bauds();
    return std::find(bauds.begin(), bauds.end(), baud) != bauds.end();
}

namespace {

class SerialPortStream final : public detail::DescriptorStream {
public:
    SerialPortStream(FileDescriptor fd, const std::string& path, const SerialSettings& settings)
        : DescriptorStream(std::move(fd), "serial " + path + " (" + detail::settings_text(settings) + ")"),
          path_(path),
          character_time_(std::chrono::microseconds(1'000'000) * settings.bits_per_character() / settings.baud) {}

    // The UART shifts the bytes out at the line's speed: they have left once that time has
    // passed (what write() waits for with tcdrain).
    Result<Instant> write_without_waiting(ByteView bytes) override {
        if (auto handed = hand_over(bytes); !handed) return handed.error();
        return std::chrono::steady_clock::now() + character_time_ * static_cast<long>(bytes.size());
    }

    ~SerialPortStream() override {
        // The exclusive flag belongs to the terminal, not to our descriptor: on a pseudo-terminal
        // whose slave stays open elsewhere it would outlive us and lock out the next program.
        ::ioctl(fd(), TIOCNXCL);
    }

    void discard_input() override { ::tcflush(fd(), TCIFLUSH); }

protected:
    // write() returning only means the bytes are in the driver's buffer; wait until the UART
    // has shifted them out, so timeouts and inter-frame gaps start when the frame has left.
    Result<void> after_write() override {
        while (::tcdrain(fd()) != 0) {
            if (errno == EINTR) continue;
            if (detail::is_hang_up(errno)) return closed_error(errno);
            return make_error(ErrorKind::link, describe() + ": waiting for the output to drain failed: " +
                                                   detail::errno_text(errno));
        }
        return {};
    }

    Error closed_error(int err) const override {
        std::string message = "serial port " + path_ +
                              " hung up: the adapter was unplugged, or the program at the other end "
                              "of the pseudo-terminal closed it";
        if (err != 0) message += " (" + detail::errno_text(err) + ")";
        return make_error(ErrorKind::link, std::move(message));
    }

private:
    std::string path_;
    std::chrono::microseconds character_time_;
};

Error busy_error(const std::string& path) {
    return make_error(ErrorKind::link, "serial port " + path +
                                           " is in use by another program — close it first "
                                           "(`fuser -v " + path + "` shows which)");
}

Error open_error(const std::string& path, int err) {
    switch (err) {
        case ENOENT:
            return make_error(ErrorKind::link, "no such port " + path +
                                                   " — check the path; is the adapter plugged in? "
                                                   "(ls /dev/serial/by-id)");
        case EACCES:
        case EPERM:
            return make_error(ErrorKind::link,
                              "permission denied opening " + path +
                                  " — add your user to the dialout group (sudo usermod -aG dialout "
                                  "$USER, then log in again)");
        case EBUSY:
        case EWOULDBLOCK:
            return busy_error(path);
        case ENXIO:
        case ENODEV:
            return make_error(ErrorKind::link, path +
                                                   " exists but no device answers behind it — is "
                                                   "the adapter plugged in and its driver loaded?");
        case EISDIR:
            return make_error(ErrorKind::link, path + " is a directory, not a serial port");
        default:
            return make_error(ErrorKind::link, "cannot open serial port " + path + ": " + detail::errno_text(err));
    }
}

Result<FileDescriptor> open_device(const std::string& path) {
    // O_NOCTTY: never become the controlling terminal. O_NONBLOCK: do not wait for carrier
    // detect on open; all waiting happens in poll().
    FileDescriptor fd(::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
    if (!fd.valid()) return open_error(path, errno);
    return fd;
}

Result<void> require_terminal(int fd, const std::string& path) {
    termios tio{};
    if (::tcgetattr(fd, &tio) == 0) return {};
    if (errno == ENOTTY || errno == EINVAL) {
        return make_error(ErrorKind::link, path +
                                               " is not a serial port (not a tty) — name a device "
                                               "such as /dev/ttyUSB0 or a pseudo-terminal link");
    }
    return open_error(path, errno);
}

// flock() is what keeps a second loopwire (and tools that honour it) out; TIOCEXCL also keeps
// out programs that do not lock, except root.
Result<void> lock_exclusively(int fd, const std::string& path) {
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
        if (errno == EWOULDBLOCK) return busy_error(path);
        return make_error(ErrorKind::link, "cannot lock serial port " + path + ": " + detail::errno_text(errno));
    }
    if (::ioctl(fd, TIOCEXCL) != 0) {
        return make_error(ErrorKind::link, "cannot claim serial port " + path +
                                               " exclusively: " + detail::errno_text(errno));
    }
    return {};
}

}  // namespace

Result<std::unique_ptr<ByteStream>> open_serial_port(const std::string& path, const SerialSettings& settings) {
    if (auto valid = detail::check_settings(settings, "serial port " + path); !valid) return valid.error();
    auto fd = open_device(path);
    if (!fd) return fd.error();
    const int raw = fd->get();
    if (auto ok = require_terminal(raw, path); !ok) return ok.error();
    if (auto ok = lock_exclusively(raw, path); !ok) return ok.error();
    // From here on the stream owns the descriptor, so its destructor clears TIOCEXCL even when
    // a later step fails.
    auto stream = std::make_unique<SerialPortStream>(std::move(*fd), path, settings);
    if (auto ok = detail::apply_serial_settings(raw, settings, "serial port " + path); !ok) return ok.error();
    if (auto ok = detail::apply_rs485(raw, settings, "serial port " + path); !ok) return ok.error();
    // Bytes that arrived before we opened belong to nobody's request.
    ::tcflush(raw, TCIOFLUSH);
    return std::unique_ptr<ByteStream>(std::move(stream));
}

}  // namespace loopwire::transport
