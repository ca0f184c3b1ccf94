#include "transport/pseudo_terminal.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/stat.h>
#include <unistd.h>

#include <climits>
#include <fstream>
#include <thread>

#include "test_support.hpp"
#include "transport/serial_port.hpp"

namespace loopwire::transport {
namespace {

using namespace std::chrono_literals;
using testing::bytes_of;
using testing::read_exactly;
using testing::TempDir;

std::string link_target(const std::string& path) {
    char target[PATH_MAX];
    const ssize_t n = ::readlink(path.c_str(), target, sizeof target);
    return n < 0 ? std::string() : std::string(target, static_cast<std::size_t>(n));
}

bool is_symlink(const std::string& path) {
    struct stat st {};
    return ::lstat(path.c_str(), &st) == 0 && S_ISLNK(st.st_mode);
}

bool path_exists(const std::string& path) {
    struct stat st {};
    return ::lstat(path.c_str(), &st) == 0;
}

std::unique_ptr<ByteStream> make_pty(const std::string& link) {
    auto pty = create_pseudo_terminal(link, SerialSettings{});
    if (!pty) ADD_FAILURE() << pty.error().message;
    return pty ? std::move(*pty) : nullptr;
}

TEST(PseudoTerminal, LinkPointsAtTheSlaveDeviceAndDescribesBoth) {
    TempDir dir;
    const std::string link = dir.file("ttyA");
    auto pty = make_pty(link);
    ASSERT_TRUE(pty);
    ASSERT_TRUE(is_symlink(link));
    const std::string target = link_target(link);
    EXPECT_EQ(target.rfind("/dev/pts/", 0), 0u) << target;
    EXPECT_EQ(pty->describe(), "pty " + link + " -> " + target);
    EXPECT_GE(pty->poll_handle(), 0);
}

TEST(PseudoTerminal, BytesFlowBothWaysThroughTheLinkPath) {
    TempDir dir;
    const std::string link = dir.file("ttyA");
    auto pty = make_pty(link);
    ASSERT_TRUE(pty);
    auto client = open_serial_port(link, SerialSettings{});
    ASSERT_TRUE(client) << client.error().message;

    const Bytes request = {0x01, 0x03, 0x00, 0x8A, 0x00, 0x01, 0xA5, 0xE0};
    ASSERT_TRUE((*client)->write(request));
    EXPECT_EQ(read_exactly(*pty, request.size()), request);

    const Bytes reply = {0x01, 0x03, 0x02, 0x00, 0x64, 0xB9, 0xAF};
    ASSERT_TRUE(pty->write(reply));
    EXPECT_EQ(read_exactly(**client, reply.size()), reply);
}

// Frames are binary: the slave must be raw (no CR/LF mapping, no XON/XOFF, no ^C, no echo)
// even for a client that does not configure the terminal itself.
TEST(PseudoTerminal, SlaveIsRawForClientsThatSetNothing) {
    TempDir dir;
    const std::string link = dir.file("ttyA");
    auto pty = make_pty(link);
    ASSERT_TRUE(pty);
    const int client = ::open(link.c_str(), O_RDWR | O_NOCTTY);
    ASSERT_GE(client, 0);

    Bytes every_value(256);
    for (std::size_t i = 0; i < every_value.size(); ++i) every_value[i] = static_cast<std::uint8_t>(i);
    ASSERT_TRUE(pty->write(every_value));
    Bytes received(256);
    std::size_t got = 0;
    while (got < received.size()) {
        pollfd entry{client, POLLIN, 0};
        ASSERT_EQ(::poll(&entry, 1, 2000), 1);
        const ssize_t n = ::read(client, received.data() + got, received.size() - got);
        ASSERT_GT(n, 0);
        got += static_cast<std::size_t>(n);
    }
    EXPECT_EQ(received, every_value);

    std::uint8_t buffer[16];
    auto echo = pty->read_some(buffer, 50ms);
    ASSERT_TRUE(echo);
    EXPECT_EQ(*echo, 0u) << "the terminal echoed what we wrote";

    ASSERT_EQ(::write(client, every_value.data(), every_value.size()), 256);
    EXPECT_EQ(read_exactly(*pty, 256), every_value);
    ::close(client);
}

// mbpoll and friends open and close the port on every run; the pseudo-terminal must carry on.
TEST(PseudoTerminal, SurvivesClientsComingAndGoing) {
    TempDir dir;
    const std::string link = dir.file("ttyA");
    auto pty = make_pty(link);
    ASSERT_TRUE(pty);
    for (int run = 0; run < 3; ++run) {
        auto client = open_serial_port(link, SerialSettings{});
        ASSERT_TRUE(client) << client.error().message;
        const Bytes message = {static_cast<std::uint8_t>(run), 0x55};
        ASSERT_TRUE((*client)->write(message));
        EXPECT_EQ(read_exactly(*pty, message.size()), message);
    }
    // Nobody has the link open now: no hang-up, just silence.
    pollfd entry{pty->poll_handle(), POLLIN, 0};
    EXPECT_EQ(::poll(&entry, 1, 0), 0) << "revents " << entry.revents;
    std::uint8_t buffer[4];
    auto quiet = pty->read_some(buffer, 20ms);
    ASSERT_TRUE(quiet) << quiet.error().message;
    EXPECT_EQ(*quiet, 0u);
}

TEST(PseudoTerminal, ReadTimesOutWithZeroBytes) {
    TempDir dir;
    auto pty = make_pty(dir.file("ttyA"));
    ASSERT_TRUE(pty);
    std::uint8_t buffer[4];
    const auto start = std::chrono::steady_clock::now();
    auto got = pty->read_some(buffer, 30ms);
    const auto elapsed = std::chrono::steady_clock::now() - start;
    ASSERT_TRUE(got);
    EXPECT_EQ(*got, 0u);
    EXPECT_GE(elapsed, 30ms);
}

TEST(PseudoTerminal, UnlimitedTimeoutStillReturnsWhatArrived) {
    TempDir dir;
    const std::string link = dir.file("ttyA");
    auto pty = make_pty(link);
    ASSERT_TRUE(pty);
    auto client = open_serial_port(link, SerialSettings{});
    ASSERT_TRUE(client) << client.error().message;
    ASSERT_TRUE((*client)->write(bytes_of("x")));
    std::uint8_t buffer[4];
    auto got = pty->read_some(buffer, std::chrono::milliseconds::max());
    ASSERT_TRUE(got) << got.error().message;
    EXPECT_EQ(*got, 1u);
}

TEST(PseudoTerminal, DiscardInputDropsWhatTheClientSent) {
    TempDir dir;
    const std::string link = dir.file("ttyA");
    auto pty = make_pty(link);
    ASSERT_TRUE(pty);
    auto client = open_serial_port(link, SerialSettings{});
    ASSERT_TRUE(client) << client.error().message;
    ASSERT_TRUE((*client)->write(bytes_of("stale reply")));
    // Wait until the bytes are there to be discarded.
    pollfd entry{pty->poll_handle(), POLLIN, 0};
    ASSERT_EQ(::poll(&entry, 1, 2000), 1);
    pty->discard_input();
    std::uint8_t buffer[32];
    auto got = pty->read_some(buffer, 30ms);
    ASSERT_TRUE(got);
    EXPECT_EQ(*got, 0u);

    ASSERT_TRUE((*client)->write(bytes_of("fresh")));
    EXPECT_EQ(read_exactly(*pty, 5), bytes_of("fresh"));
}

TEST(PseudoTerminal, RemovesTheSymlinkWhenDestroyed) {
    TempDir dir;
    const std::string link = dir.file("ttyA");
    auto pty = make_pty(link);
    ASSERT_TRUE(pty);
    ASSERT_TRUE(is_symlink(link));
    pty.reset();
    EXPECT_FALSE(path_exists(link));
}

TEST(PseudoTerminal, LeavesASymlinkSomeoneElseReplaced) {
    TempDir dir;
    const std::string link = dir.file("ttyA");
    auto pty = make_pty(link);
    ASSERT_TRUE(pty);
    ASSERT_EQ(::unlink(link.c_str()), 0);
    ASSERT_EQ(::symlink("/dev/null", link.c_str()), 0);
    pty.reset();
    EXPECT_EQ(link_target(link), "/dev/null");
}

TEST(PseudoTerminal, ReplacesAStaleSymlink) {
    TempDir dir;
    const std::string link = dir.file("ttyA");
    ASSERT_EQ(::symlink(dir.file("gone").c_str(), link.c_str()), 0);
    auto pty = make_pty(link);
    ASSERT_TRUE(pty);
    EXPECT_EQ(link_target(link).rfind("/dev/pts/", 0), 0u);
}

TEST(PseudoTerminal, RefusesToReplaceARegularFile) {
    TempDir dir;
    const std::string path = dir.file("precious");
    std::ofstream(path) << "keep me";
    auto pty = create_pseudo_terminal(path, SerialSettings{});
    ASSERT_FALSE(pty);
    EXPECT_EQ(pty.error().kind, ErrorKind::usage);
    EXPECT_NE(pty.error().message.find(path), std::string::npos) << pty.error().message;
    EXPECT_NE(pty.error().message.find("regular file"), std::string::npos) << pty.error().message;
    EXPECT_NE(pty.error().message.find("not a symlink"), std::string::npos) << pty.error().message;
    std::string content;
    std::getline(std::ifstream(path), content);
    EXPECT_EQ(content, "keep me");
}

TEST(PseudoTerminal, ReportsAMissingDirectory) {
    TempDir dir;
    const std::string path = dir.file("no-such-dir/ttyA");
    auto pty = create_pseudo_terminal(path, SerialSettings{});
    ASSERT_FALSE(pty);
    EXPECT_NE(pty.error().message.find(path), std::string::npos) << pty.error().message;
    EXPECT_NE(pty.error().message.find("directory does not exist"), std::string::npos) << pty.error().message;
}

TEST(PseudoTerminal, RejectsUnsupportedSettings) {
    TempDir dir;
    SerialSettings settings;
    settings.baud = 12345;
    auto pty = create_pseudo_terminal(dir.file("ttyA"), settings);
    ASSERT_FALSE(pty);
    EXPECT_EQ(pty.error().kind, ErrorKind::usage);
    EXPECT_NE(pty.error().message.find("12345"), std::string::npos) << pty.error().message;
    EXPECT_FALSE(path_exists(dir.file("ttyA")));
}

}  // namespace
}  // namespace loopwire::transport
