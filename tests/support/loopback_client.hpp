#pragma once
// A blocking TCP client of a loopback port, for tests of what serves HTTP there: every read is
// bounded (30 s), so a test that waits for an answer that never comes fails instead of hanging.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cstdint>
#include <string>

namespace loopwire::testing {

class LoopbackClient {
public:
    explicit LoopbackClient(std::uint16_t port) : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
        sockaddr_in address{};
        address.sin_family = AF_INET;
        address.sin_port = htons(port);
        address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        timeval bound{30, 0};
        ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &bound, sizeof bound);
        connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
    }
    ~LoopbackClient() { ::close(fd_); }
    LoopbackClient(const LoopbackClient&) = delete;
    LoopbackClient& operator=(const LoopbackClient&) = delete;

    bool connected() const { return connected_; }
    int fd() const { return fd_; }

    void send(const std::string& bytes) const { (void)!::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL); }

    // Sends `request` and reads until the server closes the connection.
    std::string ask(const std::string& request) const {
        send(request);
        std::string reply;
        char buffer[4096];
        for (ssize_t n; (n = ::recv(fd_, buffer, sizeof buffer, 0)) > 0;) reply.append(buffer, static_cast<std::size_t>(n));
        return reply;
    }

    // Sends `request` and reads one response, the connection kept.
    std::string ask_once(const std::string& request) const {
        send(request);
        return read_response();
    }

    // Sends `request` and returns what the first read brings (the head of an event stream).
    std::string ask_some(const std::string& request) const {
        send(request);
        char buffer[4096];
        const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
        return n > 0 ? std::string(buffer, static_cast<std::size_t>(n)) : std::string();
    }

    // One HTTP response: its head, then as many bytes as its Content-Length says; empty when the
    // connection ends (or the read times out) first.
    std::string read_response() const {
        std::string reply;
        char buffer[4096];
        for (;;) {
            const auto head_end = reply.find("\r\n\r\n");
            if (head_end != std::string::npos) {
                const auto length_at = reply.find("Content-Length: ");
                const std::size_t length = length_at < head_end ? std::stoul(reply.substr(length_at + 16)) : 0;
                if (reply.size() >= head_end + 4 + length) return reply;
            }
            const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
            if (n <= 0) return {};
            reply.append(buffer, static_cast<std::size_t>(n));
        }
    }

    // Reads and drops what comes until the server closes: 0 then, -1 when the read timed out.
    ssize_t read_until_closed() const {
        char buffer[4096];
        ssize_t n;
        while ((n = ::recv(fd_, buffer, sizeof buffer, 0)) > 0) {}
        return n;
    }

private:
    int fd_;
    bool connected_ = false;
};

}  // namespace loopwire::testing
