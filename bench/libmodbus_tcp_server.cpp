// libmodbus's own Modbus/TCP slave: the reference loopwire's simulator is measured against in
// tcp_throughput.sh. Nothing but libmodbus's receive/reply loop, so the figure is libmodbus's.
//
// Usage: libmodbus_tcp_server PORT [LIFETIME_SECONDS]
//   PORT 0 lets the kernel choose; the port in use is printed as "listening on port N".
//   LIFETIME_SECONDS (default 300) ends the server by itself if the driver dies.
// It serves 65536 zeroed entries in every table, as `loopwire simulate` does.
#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>

namespace {

int fail(const char* what) {
    std::fprintf(stderr, "libmodbus_tcp_server: %s: %s\n", what, modbus_strerror(errno));
    return 1;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2 || argc > 3) {
        std::fprintf(stderr, "usage: libmodbus_tcp_server PORT [LIFETIME_SECONDS]\n");
        return 2;
    }
    // SIGALRM's default action ends the process: the simplest bound on its life.
    alarm(argc == 3 ? static_cast<unsigned>(std::atoi(argv[2])) : 300u);

    modbus_t* ctx = modbus_new_tcp("127.0.0.1", std::atoi(argv[1]));
    if (ctx == nullptr) return fail("modbus_new_tcp");
    constexpr int entries = 65536;
    modbus_mapping_t* map = modbus_mapping_new(entries, entries, entries, entries);
    if (map == nullptr) return fail("modbus_mapping_new");
    int listener = modbus_tcp_listen(ctx, 1);
    if (listener < 0) return fail("modbus_tcp_listen");
    sockaddr_in bound{};
    socklen_t length = sizeof bound;
    if (getsockname(listener, reinterpret_cast<sockaddr*>(&bound), &length) != 0) return fail("getsockname");
    std::printf("listening on port %d\n", ntohs(bound.sin_port));
    std::fflush(stdout);

    for (;;) {
        if (modbus_tcp_accept(ctx, &listener) < 0) return fail("modbus_tcp_accept");
        uint8_t request[MODBUS_TCP_MAX_ADU_LENGTH];
        for (;;) {
            const int size = modbus_receive(ctx, request);
            if (size < 0) break;  // the client disconnected
            if (size > 0 && modbus_reply(ctx, request, size, map) < 0) break;
        }
        modbus_close(ctx);  // the connection's socket; the listener stays for the next client
    }
}
