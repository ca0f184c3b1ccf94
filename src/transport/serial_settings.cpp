#include "transport/serial_settings.hpp"

#include <fcntl.h>
#include <linux/serial.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>

#include "transport/file_descriptor.hpp"

namespace loopwire::transport::detail {

namespace {

constexpr std::array<std::uint32_t, 9> bauds{600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200};

// B0 for anything not in `bauds`.
speed_t speed_constant(std::uint32_t baud) {
    switch (baud) {
        case 600: return B600;
        case 1200: return B1200;
        case 2400: return B2400;
        case 4800: return B4800;
        case 9600: return B9600;
        case 19200: return B19200;
        case 38400: return B38400;
        case 57600: return B57600;
        case 115200: return B115200;
        default: return B0;
    }
}

void set_character_format(termios& tio, const SerialSettings& settings) {
    tio.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB | PARODD | CSTOPB | CRTSCTS);
    tio.c_cflag |= CLOCAL | CREAD;  // ignore modem lines: RS-485 and USB adapters have none
    tio.c_cflag |= settings.data_bits == 7 ? CS7 : CS8;
    if (settings.parity != Parity::none) {
        tio.c_cflag |= PARENB;
        // Characters with a parity error are read as NUL rather than passed on unchanged, so the
        // frame's check (CRC, LRC) fails instead of a damaged value slipping through.
        tio.c_iflag |= INPCK;
    }
    if (settings.parity == Parity::odd) tio.c_cflag |= PARODD;
    if (settings.stop_bits == 2) tio.c_cflag |= CSTOPB;
}

// Unix98 pseudo-terminal slaves (/dev/pts/N) have majors 136..143 (Documentation/admin-guide/devices.txt).
bool is_pseudo_terminal(int fd) {
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISCHR(st.st_mode)) return false;
    const unsigned int device_major = major(st.st_rdev);
    return device_major >= 136 && device_major <= 143;
}

Error settings_error(const std::string& what, const std::string& step, int err) {
    return make_error(ErrorKind::link, what + ": cannot " + step + ": " + errno_text(err));
}

}  // namespace

std::span<const std::uint32_t> supported_bauds() { return bauds; }

std::string supported_bauds_text() {
    std::string text;
    for (const auto baud : bauds) {
        if (!text.empty()) text += ", ";
        text += std::to_string(baud);
    }
    return text;
}

std::string settings_text(const SerialSettings& settings) {
    const char parity = settings.parity == Parity::none ? 'N' : settings.parity == Parity::even ? 'E' : 'O';
    return std::to_string(settings.baud) + " " + std::to_string(settings.data_bits) + parity +
           std::to_string(settings.stop_bits);
}

Result<void> check_settings(const SerialSettings& settings, const std::string& what) {
    if (speed_constant(settings.baud) == B0) {
        return make_error(ErrorKind::usage, what + ": baud " + std::to_string(settings.baud) +
                                                " is not supported (" + supported_bauds_text() + ")");
    }
    if (settings.data_bits != 7 && settings.data_bits != 8) {
        return make_error(ErrorKind::usage, what + ": " + std::to_string(settings.data_bits) +
                                                " data bits is not supported (7 or 8)");
    }
    if (settings.stop_bits != 1 && settings.stop_bits != 2) {
        return make_error(ErrorKind::usage, what + ": " + std::to_string(settings.stop_bits) +
                                                " stop bits is not supported (1 or 2)");
    }
    return {};
}

Result<void> apply_serial_settings(int fd, const SerialSettings& settings, const std::string& what) {
    if (auto valid = check_settings(settings, what); !valid) return valid;
    const speed_t speed = speed_constant(settings.baud);
    termios tio{};
    if (::tcgetattr(fd, &tio) != 0) return settings_error(what, "read terminal settings", errno);
    ::cfmakeraw(&tio);
    tio.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
    set_character_format(tio, settings);
    if (is_pseudo_terminal(fd)) {
        // Pseudo-terminals carry bytes, not bits: the kernel forces CS8 without parity on them,
        // and glibc's tcsetattr() reports EINVAL when such a refused request changes nothing
        // else (a second open). Ask only for what they keep; the speed and stop bits are stored.
        tio.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB | PARODD);
        tio.c_cflag |= CS8;
        tio.c_iflag &= ~static_cast<tcflag_t>(INPCK);
    }
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    if (::cfsetispeed(&tio, speed) != 0 || ::cfsetospeed(&tio, speed) != 0) {
        return settings_error(what, "set baud " + std::to_string(settings.baud), errno);
    }
    if (::tcsetattr(fd, TCSANOW, &tio) != 0) return settings_error(what, "apply settings", errno);

    // tcsetattr() succeeds if the driver took any part of the request, so check the speed.
    termios applied{};
    if (::tcgetattr(fd, &applied) == 0 && ::cfgetospeed(&applied) != speed) {
        return make_error(ErrorKind::link, what + ": the driver did not accept baud " +
                                               std::to_string(settings.baud) +
                                               " — try another rate the adapter supports");
    }
    return {};
}

namespace {

int whole_ms(milliseconds delay) { return static_cast<int>(std::clamp<long long>(delay.count(), 0, 1000)); }

}  // namespace

Result<void> apply_rs485(int fd, const SerialSettings& settings, const std::string& what) {
    if (settings.rs485 == Rs485::off) return {};
    serial_rs485 config{};
    config.flags = SER_RS485_ENABLED | SER_RS485_RTS_ON_SEND;
    config.delay_rts_before_send = static_cast<__u32>(whole_ms(settings.rs485_delay_before));
    config.delay_rts_after_send = static_cast<__u32>(whole_ms(settings.rs485_delay_after));
    if (::ioctl(fd, TIOCSRS485, &config) == 0) return {};
    const int err = errno;
    const std::string refusal = "kernel RS-485 direction control, which its driver does not support (TIOCSRS485: " +
                                errno_text(err) + ")";
    if (settings.rs485 == Rs485::if_supported) {
        // Said at each open, which is once for a line that runs (a gateway reopens a port only
        // after a fault, and logs that too); no record of warnings is kept across opens.
        std::fprintf(stderr, "loopwire: warning: %s: rs485=auto asked for %s; running without it\n", what.c_str(),
                     refusal.c_str());
        return {};
    }
    return make_error(ErrorKind::link, what + ": rs485 is on, which asks for " + refusal +
                                           " — use an adapter that switches direction by itself and drop rs485, or "
                                           "set rs485=auto to run without it where the driver lacks it");
}

std::optional<std::string> rs485_unsupported(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) return std::nullopt;
    serial_rs485 config{};
    const bool supported = ::ioctl(fd, TIOCGRS485, &config) == 0;
    const int err = errno;
    ::close(fd);
    if (supported) return std::nullopt;
    return "has no kernel RS-485 direction control (TIOCGRS485: " + errno_text(err) + ")";
}

}  // namespace loopwire::transport::detail
