#pragma once
// A TCP socket listening on 127.0.0.1 at a port the kernel chose: something else on a port the
// gateway is given (a Modbus TCP front that cannot open there, a service that is not a broker).
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdint>
#include <stdexcept>

namespace loopwire::testing {

class LoopbackListener {
public:
    // `backlog` 0: the kernel queues one connection, and drops the handshakes of any more while
    // it is not accepted, so they stay pending (a peer whose port no longer takes connections).
    explicit LoopbackListener(int backlog = 8) : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
        sockaddr_in address{};
        address.sin_family = AF_INET;
        address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        socklen_t size = sizeof address;
        if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&address), size) != 0 || ::listen(fd_, backlog) != 0 ||
            ::getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &size) != 0) {
            throw std::runtime_error("cannot listen on a loopback port");
        }
        port_ = ntohs(address.sin_port);
    }
    ~LoopbackListener() { ::close(fd_); }
    LoopbackListener(const LoopbackListener&) = delete;
    LoopbackListener& operator=(const LoopbackListener&) = delete;

    std::uint16_t port() const { return port_; }
    int fd() const { return fd_; }

private:
    int fd_;
    std::uint16_t port_ = 0;
};

}  // namespace loopwire::testing
