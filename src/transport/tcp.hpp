#pragma once
#include <cstdint>
#include <memory>
#include <string>

#include "transport/byte_stream.hpp"

namespace loopwire::transport {

// Connects within `timeout`; TCP_NODELAY set (request/response traffic).
Result<std::unique_ptr<ByteStream>> connect_tcp(const std::string& host, std::uint16_t port,
                                                milliseconds timeout);

class TcpListener {
public:
    // Binds and listens (SO_REUSEADDR). Port 0 picks a free port: see port().
    static Result<std::unique_ptr<TcpListener>> listen(const std::string& host, std::uint16_t port);
    ~TcpListener();
    TcpListener(const TcpListener&) = delete;
    TcpListener& operator=(const TcpListener&) = delete;

    std::uint16_t port() const { return port_; }
    int poll_handle() const { return fd_; }
    // Waits up to `timeout` for a client; nullptr on timeout.
    Result<std::unique_ptr<ByteStream>> accept(milliseconds timeout);

private:
    TcpListener(int fd, std::uint16_t port) : fd_(fd), port_(port) {}
    int fd_;
    std::uint16_t port_;
};

}  // namespace loopwire::transport
