#include "transport/serial_port.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <thread>

#include "test_support.hpp"
#include "transport/pseudo_terminal.hpp"

namespace loopwire::transport {
namespace {

using namespace std::chrono_literals;
using testing::bytes_of;
using testing::read_exactly;
using testing::TempDir;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// A pseudo-terminal to open as if it were a serial port.
struct PtyFixture : ::testing::Test {
    void SetUp() override {
        auto created = create_pseudo_terminal(link, SerialSettings{});
        ASSERT_TRUE(created) << created.error().message;
        pty = std::move(*created);
    }
    TempDir dir;
    std::string link = dir.file("ttyA");
    std::unique_ptr<ByteStream> pty;
};

using SerialPort = PtyFixture;

TEST(SerialPortOpen, MissingPathSaysWhatToCheck) {
    TempDir dir;
    const std::string path = dir.file("ttyUSB7");
    auto port = open_serial_port(path, SerialSettings{});
    ASSERT_FALSE(port);
    EXPECT_EQ(port.error().kind, ErrorKind::link);
    EXPECT_TRUE(contains(port.error().message, "no such port " + path)) << port.error().message;
    EXPECT_TRUE(contains(port.error().message, "/dev/serial/by-id")) << port.error().message;
}

TEST(SerialPortOpen, DevNullIsNotATty) {
    auto port = open_serial_port("/dev/null", SerialSettings{});
    ASSERT_FALSE(port);
    EXPECT_EQ(port.error().kind, ErrorKind::link);
    EXPECT_TRUE(contains(port.error().message, "/dev/null is not a serial port (not a tty)")) << port.error().message;
}

TEST(SerialPortOpen, DirectoryIsNotASerialPort) {
    TempDir dir;
    auto port = open_serial_port(dir.file(""), SerialSettings{});
    ASSERT_FALSE(port);
    EXPECT_TRUE(contains(port.error().message, "is a directory")) << port.error().message;
}

TEST(SerialPortOpen, RejectsUnsupportedSettingsBeforeOpening) {
    SerialSettings settings;
    settings.baud = 12345;
    auto port = open_serial_port("/dev/null", settings);
    ASSERT_FALSE(port);
    EXPECT_EQ(port.error().kind, ErrorKind::usage);
    EXPECT_TRUE(contains(port.error().message, "baud 12345")) << port.error().message;
    EXPECT_TRUE(contains(port.error().message, "115200")) << port.error().message;

    settings = SerialSettings{};
    settings.data_bits = 5;
    port = open_serial_port("/dev/null", settings);
    ASSERT_FALSE(port);
    EXPECT_TRUE(contains(port.error().message, "7 or 8")) << port.error().message;

    settings = SerialSettings{};
    settings.stop_bits = 3;
    port = open_serial_port("/dev/null", settings);
    ASSERT_FALSE(port);
    EXPECT_TRUE(contains(port.error().message, "1 or 2")) << port.error().message;
}

TEST(SerialPortBauds, SupportsTheRatesOfTheManualsAndCommonAdapters) {
    for (std::uint32_t baud : {600u, 1200u, 2400u, 4800u, 9600u, 19200u, 38400u, 57600u, 115200u}) {
        EXPECT_TRUE(is_supported_baud(baud)) << baud;
    }
    for (std::uint32_t baud : {0u, 300u, 14400u, 12345u, 230400u}) EXPECT_FALSE(is_supported_baud(baud)) << baud;
}

TEST_F(SerialPort, SecondOpenIsBusyUntilTheFirstCloses) {
    auto first = open_serial_port(link, SerialSettings{});
    ASSERT_TRUE(first) << first.error().message;
    auto second = open_serial_port(link, SerialSettings{});
    ASSERT_FALSE(second);
    EXPECT_EQ(second.error().kind, ErrorKind::link);
    EXPECT_TRUE(contains(second.error().message, link)) << second.error().message;
    EXPECT_TRUE(contains(second.error().message, "in use by another program")) << second.error().message;

    first->reset();
    auto third = open_serial_port(link, SerialSettings{});
    EXPECT_TRUE(third) << third.error().message;
}

// TIOCEXCL stays on the terminal after close while the pseudo-terminal keeps the slave open:
// it must be cleared, or the next program (not root) gets EBUSY.
TEST_F(SerialPort, ExclusiveFlagIsClearedOnClose) {
    const int observer = ::open(link.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (observer < 0 && errno == EBUSY) GTEST_SKIP() << "cannot observe the flag without root";
    ASSERT_GE(observer, 0);
    int exclusive = -1;
    {
        auto port = open_serial_port(link, SerialSettings{});
        ASSERT_TRUE(port) << port.error().message;
        ASSERT_EQ(::ioctl(observer, TIOCGEXCL, &exclusive), 0);
        EXPECT_EQ(exclusive, 1);
    }
    ASSERT_EQ(::ioctl(observer, TIOCGEXCL, &exclusive), 0);
    EXPECT_EQ(exclusive, 0);
    ::close(observer);
}

TEST_F(SerialPort, AppliesSpeedStopBitsAndNonBlockingReads) {
    SerialSettings settings;
    settings.baud = 9600;
    settings.parity = Parity::odd;
    settings.stop_bits = 2;
    auto port = open_serial_port(link, settings);
    ASSERT_TRUE(port) << port.error().message;
    EXPECT_EQ((*port)->describe(), "serial " + link + " (9600 8O2)");

    termios tio{};
    ASSERT_EQ(::tcgetattr((*port)->poll_handle(), &tio), 0);
    EXPECT_EQ(::cfgetospeed(&tio), static_cast<speed_t>(B9600));
    EXPECT_EQ(::cfgetispeed(&tio), static_cast<speed_t>(B9600));
    EXPECT_TRUE(tio.c_cflag & CSTOPB);
    EXPECT_TRUE(tio.c_cflag & CLOCAL);
    EXPECT_FALSE(tio.c_cflag & CRTSCTS);
    EXPECT_FALSE(tio.c_lflag & (ICANON | ECHO | ISIG));
    EXPECT_FALSE(tio.c_iflag & (IXON | IXOFF | ICRNL));
    EXPECT_FALSE(tio.c_oflag & OPOST);
    EXPECT_EQ(tio.c_cc[VMIN], 0);
    EXPECT_EQ(tio.c_cc[VTIME], 0);
}

TEST_F(SerialPort, Rs485OnAPseudoTerminalFailsWithAClearMessage) {
    SerialSettings settings;
    settings.rs485 = Rs485::on;
    auto port = open_serial_port(link, settings);
    ASSERT_FALSE(port);
    EXPECT_EQ(port.error().kind, ErrorKind::link);
    const std::string& message = port.error().message;
    EXPECT_TRUE(contains(message, link)) << message;
    EXPECT_TRUE(contains(message, "RS-485")) << message;
    EXPECT_TRUE(contains(message, "Inappropriate ioctl for device")) << message;
    EXPECT_TRUE(contains(message, "drop rs485")) << message;
    EXPECT_TRUE(contains(message, "rs485=auto")) << message;
    // The failed open must not leave the port locked.
    auto plain = open_serial_port(link, SerialSettings{});
    EXPECT_TRUE(plain) << plain.error().message;
}

// "auto" opens a port whose driver lacks RS-485 control and says so on stderr, once for the open.
TEST_F(SerialPort, Rs485AutoOnAPseudoTerminalRunsWithoutItAndSaysSo) {
    SerialSettings settings;
    settings.rs485 = Rs485::if_supported;
    settings.rs485_delay_before = std::chrono::milliseconds(2);
    ::testing::internal::CaptureStderr();
    auto port = open_serial_port(link, settings);
    const std::string said = ::testing::internal::GetCapturedStderr();
    ASSERT_TRUE(port) << port.error().message;
    EXPECT_TRUE(contains(said, "warning: serial port " + link)) << said;
    EXPECT_TRUE(contains(said, "rs485=auto")) << said;
    EXPECT_TRUE(contains(said, "running without it")) << said;
    EXPECT_EQ(said.find("rs485=auto"), said.rfind("rs485=auto")) << "said more than once: " << said;
    // It still carries bytes.
    const Bytes frame{0x01, 0x03, 0x00, 0x00, 0x00, 0x01, 0x84, 0x0A};
    ASSERT_TRUE((*port)->write(frame));
    EXPECT_EQ(read_exactly(*pty, frame.size(), 10s), frame);
}

TEST_F(SerialPort, ReadTimesOutWithZeroBytes) {
    auto port = open_serial_port(link, SerialSettings{});
    ASSERT_TRUE(port) << port.error().message;
    std::uint8_t buffer[8];
    const auto start = std::chrono::steady_clock::now();
    auto got = (*port)->read_some(buffer, 40ms);
    const auto elapsed = std::chrono::steady_clock::now() - start;
    ASSERT_TRUE(got) << got.error().message;
    EXPECT_EQ(*got, 0u);
    EXPECT_GE(elapsed, 40ms);
}

// Far more than the terminal buffers hold: write() must carry on through partial writes
// and EAGAIN while the other side reads.
TEST_F(SerialPort, LargeWritesArriveWhole) {
    auto port = open_serial_port(link, SerialSettings{});
    ASSERT_TRUE(port) << port.error().message;
    Bytes payload(64 * 1024);
    for (std::size_t i = 0; i < payload.size(); ++i) payload[i] = static_cast<std::uint8_t>(i * 7 + i / 256);
    Bytes received;
    std::thread reader([&] { received = read_exactly(*pty, payload.size(), 10s); });
    auto written = (*port)->write(payload);
    reader.join();
    ASSERT_TRUE(written) << written.error().message;
    EXPECT_EQ(received.size(), payload.size());
    EXPECT_TRUE(received == payload);
}

TEST_F(SerialPort, DiscardInputDropsStaleBytes) {
    auto port = open_serial_port(link, SerialSettings{});
    ASSERT_TRUE(port) << port.error().message;
    ASSERT_TRUE(pty->write(bytes_of("late reply")));
    // Discarded once they have reached the port (on a loaded machine that can take a while).
    pollfd readable{(*port)->poll_handle(), POLLIN, 0};
    ASSERT_EQ(::poll(&readable, 1, 10000), 1) << "the bytes written never reached the port";
    (*port)->discard_input();
    std::uint8_t buffer[32];
    auto got = (*port)->read_some(buffer, 30ms);
    ASSERT_TRUE(got);
    EXPECT_EQ(*got, 0u);
    ASSERT_TRUE(pty->write(bytes_of("next")));
    EXPECT_EQ(read_exactly(**port, 4), bytes_of("next"));
}

TEST_F(SerialPort, OtherSideClosingIsALinkError) {
    auto port = open_serial_port(link, SerialSettings{});
    ASSERT_TRUE(port) << port.error().message;
    pty.reset();
    std::uint8_t buffer[8];
    auto got = (*port)->read_some(buffer, 1s);
    ASSERT_FALSE(got);
    EXPECT_EQ(got.error().kind, ErrorKind::link);
    EXPECT_TRUE(contains(got.error().message, link)) << got.error().message;
    EXPECT_TRUE(contains(got.error().message, "hung up")) << got.error().message;
}

}  // namespace
}  // namespace loopwire::transport
