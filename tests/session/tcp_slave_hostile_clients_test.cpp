// Clients that misbehave cost the TCP slave bounded resources and cost other clients nothing:
// real sockets on 127.0.0.1, a second client that keeps polling and must keep its latency.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>

#include <cstdio>
#include <vector>

#include "support/eventually.hpp"
#include "tcp_test_client.hpp"

namespace loopwire::session {
namespace {

using testing::RawClient;
using testing::ServedSlave;
using namespace std::chrono_literals;

constexpr auto latency_bound = 50ms;

// FC3 for 125 registers: 12 request bytes that ask for 259 reply bytes.
Bytes read_many(std::uint16_t transaction) { return codec::mbap_encode(transaction, 1, Bytes{0x03, 0x00, 0x00, 0x00, 0x7D}); }

// Sends what the socket takes without waiting; false once the server has closed the connection.
bool push(int fd, const Bytes& bytes) {
    std::size_t done = 0;
    while (done < bytes.size()) {
        const ssize_t n = ::send(fd, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n > 0) {
            done += static_cast<std::size_t>(n);
            continue;
        }
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return true;  // full for now
        return false;  // EPIPE or ECONNRESET: closed by the server
    }
    return true;
}

// A client pipelines requests and never reads its replies. Its queue passes the server's bound
// and it is closed; all along, another client's requests are answered within the latency bound.
TEST(TcpSlaveHostileClients, AClientThatNeverReadsIsClosedWhileAnotherKeepsItsLatency) {
    ServedSlave served(UnitMap{{1, std::make_shared<RegisterBank>()}});
    RawClient polling(served.port());
    RawClient hog(served.port(), 4096);
    ASSERT_TRUE(polling.connected() && hog.connected());
    Bytes batch;
    for (std::uint16_t i = 0; i < 200; ++i) {
        const Bytes one = read_many(i);
        batch.insert(batch.end(), one.begin(), one.end());
    }
    const auto deadline = testing::Clock::now() + 30s;
    std::uint16_t transaction = 1;
    bool closed = false;
    std::size_t steps = 0;
    while (!closed && testing::Clock::now() < deadline) {
        closed = !push(hog.fd(), batch);
        ++steps;
        EXPECT_LT(testing::poll_latency(polling, transaction++), latency_bound) << "at step " << steps;
    }
    ASSERT_TRUE(closed) << "the client that never reads was not closed within 30 s (" << steps << " batches of 200 requests)";
    EXPECT_GT(steps, 2u) << "closed before its queue can have passed the bound";
    EXPECT_LT(testing::poll_latency(polling, transaction), latency_bound);
}

// The polling client connects first and keeps polling while 500 others connect and go quiet
// halfway through a header, then goes on polling with all of them held open.
TEST(TcpSlaveHostileClients, FiveHundredIdleConnectionsDoNotSlowAPollingClient) {
    ServedSlave served(UnitMap{{1, std::make_shared<RegisterBank>()}});
    RawClient polling(served.port());
    std::uint16_t transaction = 1;
    std::vector<std::unique_ptr<RawClient>> idle;
    for (int i = 0; i < 500; ++i) {
        idle.push_back(std::make_unique<RawClient>(served.port()));
        ASSERT_TRUE(idle.back()->connected()) << "connection " << i;
        // Half an MBAP header: the server holds a partial frame for each of them.
        ASSERT_TRUE(idle.back()->send(Bytes{0x00, 0x01, 0x00}));
        if (i % 50 == 49) {
            EXPECT_LT(testing::poll_latency(polling, transaction++), latency_bound) << "after " << i + 1 << " connections";
        }
    }
    for (int i = 0; i < 100; ++i) {
        EXPECT_LT(testing::poll_latency(polling, transaction++), latency_bound) << "request " << transaction;
    }
    // The idle ones were accepted and their partial frames kept: completing one gets it answered.
    RawClient& last = *idle.back();
    ASSERT_TRUE(last.send(Bytes{0x00, 0x00, 0x06, 0x01, 0x03, 0x00, 0x00, 0x00, 0x01}));
    EXPECT_EQ(last.receive(11), (Bytes{0x00, 0x01, 0x00, 0x00, 0x00, 0x05, 0x01, 0x03, 0x02, 0x00, 0x00}));
}

// ---- a server short of file descriptors -------------------------------------------------
//
// The server runs in a forked child whose RLIMIT_NOFILE is 64 (this process keeps its own
// limit, and its clients need descriptors of their own). The child names its port on one pipe,
// then on each command byte on another it measures its CPU time over an idle second and
// answers in microseconds.

// Under UBSan, the first check of a virtual call on each dynamic type asks the kernel whether
// the vtable is readable through a pipe (sanitizer_common's IsAccessibleMemoryRange). With no
// descriptor free that pipe cannot be made and the check reports a false "invalid vptr". One
// whole connection -- a request answered, then the client's end seen and the connection
// closed -- checks, while descriptors are plentiful, every type the crowd's connections meet.
void live_one_connection(std::uint16_t port) {
    RawClient client(port);
    if (!client.send(testing::read_one_register(1, 0)) || client.receive(11).size() != 11) ::_exit(7);
    ::shutdown(client.fd(), SHUT_WR);
    if (!client.closed_by_server_within(5s)) ::_exit(8);
}

void run_short_of_descriptors(int report_fd, int command_fd) {
    const rlimit limit{64, 64};
    if (::setrlimit(RLIMIT_NOFILE, &limit) != 0) ::_exit(3);
    try {
        ServedSlave served(UnitMap{{1, std::make_shared<RegisterBank>()}});
        const std::uint16_t port = served.port();
        live_one_connection(port);
        if (::write(report_fd, &port, sizeof port) != sizeof port) ::_exit(4);
        char command = 0;
        while (::read(command_fd, &command, 1) == 1) {
            timespec before{};
            timespec after{};
            ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &before);
            std::this_thread::sleep_for(1s);  // the idle second being measured
            ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &after);
            const long long used_us = (after.tv_sec - before.tv_sec) * 1000000LL + (after.tv_nsec - before.tv_nsec) / 1000;
            if (::write(report_fd, &used_us, sizeof used_us) != sizeof used_us) ::_exit(5);
        }
    } catch (...) {
        ::_exit(6);
    }
    ::_exit(0);
}

class ServerShortOfDescriptors {
public:
    ServerShortOfDescriptors() {
        int report[2];
        int command[2];
        if (::pipe2(report, O_CLOEXEC) != 0 || ::pipe2(command, O_CLOEXEC) != 0) throw std::runtime_error("pipe2 failed");
        pid_ = ::fork();
        if (pid_ < 0) throw std::runtime_error("fork failed");
        if (pid_ == 0) {
            ::close(report[0]);
            ::close(command[1]);
            run_short_of_descriptors(report[1], command[0]);
        }
        ::close(report[1]);
        ::close(command[0]);
        report_ = report[0];
        command_ = command[1];
        std::uint16_t port = 0;
        if (!read_report(&port, sizeof port, 5s)) throw std::runtime_error("the server child named no port");
        port_ = port;
    }
    ~ServerShortOfDescriptors() {
        ::close(command_);  // end of commands: the child exits
        int status = 0;
        // A moment to exit by itself, then killed.
        if (!loopwire::testing::eventually([&] { return ::waitpid(pid_, &status, WNOHANG) != 0; }, 1s)) {
            ::kill(pid_, SIGKILL);
            ::waitpid(pid_, &status, 0);
        }
        ::close(report_);
    }
    ServerShortOfDescriptors(const ServerShortOfDescriptors&) = delete;
    ServerShortOfDescriptors& operator=(const ServerShortOfDescriptors&) = delete;

    std::uint16_t port() const { return port_; }

    // The child's CPU time over one idle second.
    std::chrono::microseconds idle_cpu() {
        const char command = 'm';
        long long used_us = -1;
        if (::write(command_, &command, 1) != 1 || !read_report(&used_us, sizeof used_us, 5s)) {
            ADD_FAILURE() << "the server child did not measure its CPU time";
        }
        return std::chrono::microseconds(used_us);
    }

private:
    bool read_report(void* into, std::size_t size, std::chrono::milliseconds wait) {
        pollfd entry{report_, POLLIN, 0};
        if (::poll(&entry, 1, static_cast<int>(wait.count())) != 1) return false;
        return ::read(report_, into, size) == static_cast<ssize_t>(size);
    }

    pid_t pid_ = -1;
    int report_ = -1;
    int command_ = -1;
    std::uint16_t port_ = 0;
};

// 100 connection attempts against a server allowed 64 descriptors: accept() fails with EMFILE
// while they wait in the backlog. The client connected first keeps being answered, the server
// does not spin on the failing accept(), and it accepts again once descriptors are free.
TEST(TcpSlaveHostileClients, ShortOfDescriptorsTheServerKeepsServingAndDoesNotSpin) {
    ServerShortOfDescriptors server;
    RawClient polling(server.port());
    ASSERT_LT(testing::poll_latency(polling, 1), latency_bound);
    std::vector<std::unique_ptr<RawClient>> crowd;
    for (int i = 0; i < 100; ++i) {
        crowd.push_back(std::make_unique<RawClient>(server.port()));
        ASSERT_TRUE(crowd.back()->connected()) << "connection attempt " << i;
    }
    for (std::uint16_t transaction = 2; transaction <= 50; ++transaction) {
        EXPECT_LT(testing::poll_latency(polling, transaction), latency_bound) << "request " << transaction;
    }
    EXPECT_LT(server.idle_cpu(), 50ms) << "CPU used in an idle second while accept() fails";
    EXPECT_LT(testing::poll_latency(polling, 51), latency_bound);

    crowd.clear();  // descriptors come free as the server sees these close
    RawClient late(server.port());
    EXPECT_LT(testing::poll_latency(late, 1), 2s);
}

}  // namespace
}  // namespace loopwire::session
