#include "transport/tcp.hpp"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string_view>

#include "transport/descriptor_stream.hpp"

namespace loopwire::transport {

using detail::FileDescriptor;

namespace {

// "[::1]:1502" for IPv6 literals, "host:502" otherwise.
std::string endpoint_text(const std::string& host, std::uint16_t port) {
    const bool ipv6 = host.find(':') != std::string::npos;
    return (ipv6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
}

// The connecting client's address, as numbers: "127.0.0.1:50312".
std::string peer_text(int fd) {
    sockaddr_storage address{};
    socklen_t length = sizeof address;
    if (::getpeername(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) return "unknown peer";
    char host[NI_MAXHOST];
    char service[NI_MAXSERV];
    if (::getnameinfo(reinterpret_cast<sockaddr*>(&address), length, host, sizeof host, service,
                      sizeof service, NI_NUMERICHOST | NI_NUMERICSERV) != 0) {
        return "unknown peer";
    }
    const bool ipv6 = std::string_view(host).find(':') != std::string_view::npos;
    return (ipv6 ? "[" + std::string(host) + "]" : std::string(host)) + ":" + service;
}

class TcpStream final : public detail::DescriptorStream {
public:
    TcpStream(FileDescriptor fd, std::string description)
        : DescriptorStream(std::move(fd), std::move(description)) {}

protected:
    // MSG_NOSIGNAL: a peer that went away must be an error value, not a SIGPIPE that kills us.
    ssize_t transmit(ByteView bytes) override {
        return ::send(fd(), bytes.data(), bytes.size(), MSG_NOSIGNAL);
    }

    bool reads_without_waiting() const override { return true; }

    Error closed_error(int err) const override {
        const char* what = err == ECONNRESET ? "connection reset by peer" : "connection closed by peer";
        return make_error(ErrorKind::link, describe() + ": " + what);
    }
};

// Requests and replies are small and answered one by one: Nagle's delay would only add latency.
void disable_nagle(int fd) {
    const int on = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
}

struct AddressListDeleter {
    void operator()(addrinfo* list) const { ::freeaddrinfo(list); }
};
using AddressList = std::unique_ptr<addrinfo, AddressListDeleter>;

Result<AddressList> resolve(const std::string& host, std::uint16_t port, bool passive) {
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_NUMERICSERV | (passive ? AI_PASSIVE : 0);
    addrinfo* list = nullptr;
    const std::string service = std::to_string(port);
    const int rc = ::getaddrinfo(host.empty() ? nullptr : host.c_str(), service.c_str(), &hints, &list);
    if (rc != 0) {
        const std::string reason = rc == EAI_SYSTEM ? detail::errno_text(errno) : ::gai_strerror(rc);
        const char* advice = rc == EAI_AGAIN ? " — the name server did not answer; try again or use an IP address"
                                             : " — check the name, or use an IP address";
        return make_error(ErrorKind::link, "unknown host '" + host + "' (" + reason + ")" + advice);
    }
    return AddressList(list);
}

Error connect_error(const std::string& endpoint, int err) {
    switch (err) {
        case ECONNREFUSED:
            return make_error(ErrorKind::link, "nothing listening at " + endpoint + " — is the server running?");
        case ENETUNREACH:
        case EHOSTUNREACH:
            return make_error(ErrorKind::link, endpoint + " is unreachable (" + detail::errno_text(err) +
                                                   ") — check the address and the network");
        default:
            return make_error(ErrorKind::link, "cannot connect to " + endpoint + ": " + detail::errno_text(err));
    }
}

// One address: non-blocking connect, then poll() for the outcome until `deadline`.
// An error of kind timeout means the deadline passed.
Result<FileDescriptor> connect_address(const addrinfo& address, const std::string& endpoint, Instant deadline,
                                       std::chrono::milliseconds timeout) {
    FileDescriptor fd(::socket(address.ai_family, address.ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC,
                               address.ai_protocol));
    if (!fd.valid()) return make_error(ErrorKind::link, "cannot create a socket: " + detail::errno_text(errno));
    if (::connect(fd.get(), address.ai_addr, address.ai_addrlen) == 0) return fd;
    if (errno != EINPROGRESS) return connect_error(endpoint, errno);
    auto ready = detail::wait_for_events(fd.get(), POLLOUT, deadline);
    if (!ready) return ready.error();
    if (*ready == 0) {
        return make_error(ErrorKind::timeout, "no answer from " + endpoint + " within " +
                                                  std::to_string(timeout.count()) +
                                                  " ms — is the host up, and is a firewall dropping the port?");
    }
    int err = 0;
    socklen_t length = sizeof err;
    if (::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &err, &length) != 0) err = errno;
    if (err != 0) return connect_error(endpoint, err);
    return fd;
}

}  // namespace

Result<std::unique_ptr<ByteStream>> connect_tcp(const std::string& host, std::uint16_t port, milliseconds timeout) {
    if (host.empty()) return make_error(ErrorKind::usage, "connect: empty host name");
    const std::string endpoint = endpoint_text(host, port);
    // The name lookup itself is not bounded by `timeout` (getaddrinfo cannot be interrupted);
    // it counts against it, though, so a slow lookup leaves less time to connect.
    const Instant deadline = detail::deadline_after(timeout);
    auto addresses = resolve(host, port, false);
    if (!addresses) return addresses.error();
    // A name can resolve to several addresses (IPv6 and IPv4): the first that answers wins,
    // and the error reported is the last one's.
    Error last = make_error(ErrorKind::link, "cannot connect to " + endpoint + ": no address");
    for (const addrinfo* address = addresses->get(); address != nullptr; address = address->ai_next) {
        auto fd = connect_address(*address, endpoint, deadline, timeout);
        if (fd) {
            disable_nagle(fd->get());
            return std::unique_ptr<ByteStream>(std::make_unique<TcpStream>(std::move(*fd), "tcp " + endpoint));
        }
        last = fd.error();
        if (last.kind == ErrorKind::timeout) break;
    }
    return last;
}

namespace {

Error listen_error(const std::string& endpoint, std::uint16_t port, int err) {
    switch (err) {
        case EADDRINUSE:
            return make_error(ErrorKind::link, endpoint + " is already in use — stop the other server or "
                                                          "choose another port (port 0 picks a free one)");
        case EACCES:
            return make_error(ErrorKind::link, "no permission to listen on " + endpoint +
                                                   (port < 1024 ? " — ports below 1024 need root or "
                                                                  "CAP_NET_BIND_SERVICE; choose one from 1024 up"
                                                                : ""));
        case EADDRNOTAVAIL:
            return make_error(ErrorKind::link, "cannot listen on " + endpoint +
                                                   ": that address does not belong to this machine");
        default:
            return make_error(ErrorKind::link, "cannot listen on " + endpoint + ": " + detail::errno_text(err));
    }
}

// 0 on success, otherwise the errno of the step that failed.
int bind_and_listen(int fd, const addrinfo& address) {
    // Lets a restarted server take its port back while old connections sit in TIME_WAIT.
    const int on = 1;
    if (::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on) != 0) return errno;
    if (::bind(fd, address.ai_addr, address.ai_addrlen) != 0) return errno;
    if (::listen(fd, SOMAXCONN) != 0) return errno;
    return 0;
}

std::uint16_t local_port(int fd) {
    sockaddr_storage address{};
    socklen_t length = sizeof address;
    if (::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) return 0;
    // Copied out rather than cast: sockaddr_storage is only storage for the real type.
    if (address.ss_family == AF_INET6) {
        sockaddr_in6 ipv6{};
        std::memcpy(&ipv6, &address, sizeof ipv6);
        return ntohs(ipv6.sin6_port);
    }
    sockaddr_in ipv4{};
    std::memcpy(&ipv4, &address, sizeof ipv4);
    return ntohs(ipv4.sin_port);
}

}  // namespace

Result<std::unique_ptr<TcpListener>> TcpListener::listen(const std::string& host, std::uint16_t port) {
    const std::string endpoint = endpoint_text(host.empty() ? "*" : host, port);
    auto addresses = resolve(host, port, true);
    if (!addresses) return addresses.error();
    int err = EADDRNOTAVAIL;
    for (const addrinfo* address = addresses->get(); address != nullptr; address = address->ai_next) {
        FileDescriptor fd(::socket(address->ai_family, address->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC,
                                   address->ai_protocol));
        if (!fd.valid()) {
            err = errno;
            continue;
        }
        err = bind_and_listen(fd.get(), *address);
        if (err == 0) {
            const std::uint16_t bound = local_port(fd.get());
            return std::unique_ptr<TcpListener>(new TcpListener(fd.release(), bound));
        }
    }
    return listen_error(endpoint, port, err);
}

TcpListener::~TcpListener() {
    if (fd_ >= 0) ::close(fd_);
}

Result<std::unique_ptr<ByteStream>> TcpListener::accept(milliseconds timeout) {
    const Instant deadline = detail::deadline_after(timeout);
    for (;;) {
        auto ready = detail::wait_for_events(fd_, POLLIN, deadline);
        if (!ready) return ready.error();
        if (*ready == 0) return std::unique_ptr<ByteStream>();
        FileDescriptor client(::accept4(fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
        if (client.valid()) {
            disable_nagle(client.get());
            std::string description = "tcp " + peer_text(client.get());
            return std::unique_ptr<ByteStream>(std::make_unique<TcpStream>(std::move(client), std::move(description)));
        }
        // The client may have given up between poll() and accept(): wait for the next one.
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ECONNABORTED || errno == EINTR ||
            errno == EPROTO) {
            continue;
        }
        return make_error(ErrorKind::link, "accepting a connection on port " + std::to_string(port_) +
                                               " failed: " + detail::errno_text(errno));
    }
}

}  // namespace loopwire::transport
