#pragma once
// A raw Modbus/TCP client on a real loopback socket, for tests of the TCP slave: it writes and
// reads exact bytes, and every wait has a deadline that fails the test loudly when it passes.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <memory>
#include <stop_token>
#include <thread>

#include "codec/tcp.hpp"
#include "simulation/register_bank.hpp"
#include "session/slave.hpp"
#include "transport/tcp.hpp"

namespace loopwire::session::testing {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

class RawClient {
public:
    // Connects to 127.0.0.1:`port`. `receive_buffer` > 0 shrinks the socket's receive buffer
    // (set before connecting, so the window is small from the start).
    explicit RawClient(std::uint16_t port, int receive_buffer = 0) {
        fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (fd_ < 0) {
            ADD_FAILURE() << "socket(): " << std::strerror(errno);
            return;
        }
        if (receive_buffer > 0) ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
        const int on = 1;
        ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
        sockaddr_in address{};
        address.sin_family = AF_INET;
        address.sin_port = htons(port);
        address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        if (::connect(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
            ADD_FAILURE() << "connect(): " << std::strerror(errno);
            ::close(fd_);
            fd_ = -1;
            return;
        }
        connected_ = true;
    }
    ~RawClient() {
        if (fd_ >= 0) ::close(fd_);
    }
    RawClient(const RawClient&) = delete;
    RawClient& operator=(const RawClient&) = delete;

    bool connected() const { return connected_; }
    int fd() const { return fd_; }

    // Every byte written within `wait`, or a test failure.
    bool send(ByteView bytes, milliseconds wait = milliseconds(2000)) {
        const auto deadline = Clock::now() + wait;
        std::size_t done = 0;
        while (done < bytes.size()) {
            const ssize_t n = ::send(fd_, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL | MSG_DONTWAIT);
            if (n > 0) {
                done += static_cast<std::size_t>(n);
            } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
                if (!wait_for(POLLOUT, deadline)) {
                    ADD_FAILURE() << "could not send within " << wait.count() << " ms";
                    return false;
                }
            } else {
                ADD_FAILURE() << "send(): " << std::strerror(errno);
                return false;
            }
        }
        return true;
    }

    // Exactly `size` bytes within `wait`, or a test failure (and what did come).
    Bytes receive(std::size_t size, milliseconds wait = milliseconds(2000)) {
        const auto deadline = Clock::now() + wait;
        Bytes got(size);
        std::size_t done = 0;
        while (done < size) {
            if (!wait_for(POLLIN, deadline)) {
                ADD_FAILURE() << "received " << done << " of " << size << " bytes within " << wait.count() << " ms";
                break;
            }
            const ssize_t n = ::recv(fd_, got.data() + done, size - done, MSG_DONTWAIT);
            if (n <= 0) {
                ADD_FAILURE() << "connection ended after " << done << " of " << size << " bytes";
                break;
            }
            done += static_cast<std::size_t>(n);
        }
        got.resize(done);
        return got;
    }

    // True when the server closes the connection within `wait` (bytes still coming are skipped).
    bool closed_by_server_within(milliseconds wait) {
        const auto deadline = Clock::now() + wait;
        std::array<std::uint8_t, 4096> sink{};
        while (wait_for(POLLIN, deadline)) {
            const ssize_t n = ::recv(fd_, sink.data(), sink.size(), MSG_DONTWAIT);
            if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) return true;
        }
        return false;
    }

private:
    bool wait_for(short events, Clock::time_point deadline) const {
        for (;;) {
            const auto left = std::chrono::ceil<milliseconds>(deadline - Clock::now());
            if (left.count() <= 0) return false;
            pollfd entry{fd_, events, 0};
            const int ready = ::poll(&entry, 1, static_cast<int>(left.count()));
            if (ready > 0) return true;
            if (ready < 0 && errno != EINTR) return false;
        }
    }

    int fd_ = -1;
    bool connected_ = false;
};

// A read of one holding register at `address`, as an MBAP request.
inline Bytes read_one_register(std::uint16_t transaction, std::uint16_t address, std::uint8_t unit = 1) {
    Bytes pdu{0x03};
    append_be16(pdu, address);
    append_be16(pdu, 1);
    return codec::mbap_encode(transaction, unit, pdu);
}

// One request/reply on `client`, returning how long the reply took; a wrong or missing reply
// fails the test.
inline std::chrono::microseconds poll_latency(RawClient& client, std::uint16_t transaction) {
    const auto start = Clock::now();
    client.send(read_one_register(transaction, 0));
    const Bytes reply = client.receive(11);  // MBAP 7 + 03 02 hi lo
    const auto took = std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - start);
    EXPECT_EQ(reply.size(), 11u);
    if (reply.size() == 11u) {
        EXPECT_EQ(read_be16(reply, 0), transaction);
        EXPECT_EQ(reply[7], 0x03);
    }
    return took;
}

// A slave serving `units` on a kernel-chosen loopback port, in its own thread, until destroyed.
class ServedSlave {
public:
    explicit ServedSlave(UnitMap units, std::string link = "tcp://127.0.0.1:0", SlaveOptions options = {})
        : slave_(*transport::parse_link_url(link), std::move(units), std::move(options)) {
        auto listener = transport::TcpListener::listen("127.0.0.1", 0);
        if (!listener) throw std::runtime_error(listener.error().message);
        listener_ = std::move(*listener);
        server_ = std::jthread([this](std::stop_token stop) { result_ = slave_.serve_listener(*listener_, stop); });
    }
    ~ServedSlave() { stop(); }
    ServedSlave(const ServedSlave&) = delete;
    ServedSlave& operator=(const ServedSlave&) = delete;

    std::uint16_t port() const { return listener_->port(); }
    Slave& slave() { return slave_; }
    void stop() {
        if (!server_.joinable()) return;
        server_.request_stop();
        server_.join();
    }
    bool served_ok() const { return result_.ok(); }

private:
    Slave slave_;
    std::unique_ptr<transport::TcpListener> listener_;
    Result<void> result_;
    std::jthread server_;
};

}  // namespace loopwire::session::testing
