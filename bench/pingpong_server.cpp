// The floor for a loopback request/response server: no Modbus logic at all. Each request is one
// read of the 12 bytes of an FC3 request ("read 10 holding registers") and one write of the
// 29-byte reply (MBAP 7 + function, byte count, 20 data bytes), with the request's transaction
// id and unit copied so a real Modbus client accepts it. One client at a time, blocking calls.
//
// Usage: pingpong_server [PORT]   (0 or nothing: a free port, named on stderr as
//        "listening on port N" like the other servers tcp_throughput.sh runs)
#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace {

constexpr std::size_t request_size = 12;  // MBAP 7 + FC3 PDU 5
constexpr std::size_t reply_size = 29;    // MBAP 7 + 03 14h + 10 registers

// Serves one client until it leaves; every request gets one read and one write.
void serve(int client) {
    std::uint8_t request[request_size];
    std::uint8_t reply[reply_size] = {};
    reply[5] = reply_size - 6;  // MBAP length: unit + PDU
    reply[7] = 0x03;
    reply[8] = 20;
    for (;;) {
        const ssize_t got = ::recv(client, request, sizeof request, MSG_WAITALL);
        if (got != static_cast<ssize_t>(sizeof request)) return;
        reply[0] = request[0];
        reply[1] = request[1];
        reply[6] = request[6];
        if (::send(client, reply, sizeof reply, MSG_NOSIGNAL) != static_cast<ssize_t>(sizeof reply)) return;
    }
}

}  // namespace

int main(int argc, char** argv) {
    const int port = argc > 1 ? std::atoi(argv[1]) : 0;
    const int listener = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const int on = 1;
    ::setsockopt(listener, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t length = sizeof address;
    if (listener < 0 || ::bind(listener, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
        ::listen(listener, 16) != 0 || ::getsockname(listener, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
        std::fprintf(stderr, "pingpong_server: cannot listen: %s\n", std::strerror(errno));
        return 1;
    }
    std::fprintf(stderr, "pingpong_server: listening on port %u\n", ntohs(address.sin_port));
    for (;;) {
        const int client = ::accept4(listener, nullptr, nullptr, SOCK_CLOEXEC);
        if (client < 0) continue;
        ::setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
        serve(client);
        ::close(client);
    }
}
