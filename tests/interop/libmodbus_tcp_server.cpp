// A libmodbus Modbus/TCP slave with known contents, for loopwire's master side to talk to.
//
// Usage: libmodbus_tcp_server PORT [LIFETIME_SECONDS]
//   PORT 0 lets the kernel choose a free port, so tests never race for one; the port in use
//   is printed on stdout as "listening on port N" once the server accepts connections.
//   LIFETIME_SECONDS (default 45) ends the server by itself, so a killed test cannot leave it
//   running.
//
// Contents (table_size entries from address 0 in every table; past them libmodbus answers
// exception 2, illegal data address):
//   holding register a = 0x1000 + a, input register a = 100 * a,
//   coil a = (a % 4 == 1), discrete input a = (a % 5 == 0).
// libmodbus's TCP slave answers every unit id (PEERS.md).
#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>

namespace {

constexpr int table_size = 200;

int fail(const char* what) {
    std::fprintf(stderr, "libmodbus_tcp_server: %s: %s\n", what, modbus_strerror(errno));
    return 1;
}

void preset(modbus_mapping_t& map) {
    for (int a = 0; a < table_size; ++a) {
        map.tab_registers[a] = static_cast<uint16_t>(0x1000 + a);
        map.tab_input_registers[a] = static_cast<uint16_t>(100 * a);
        map.tab_bits[a] = a % 4 == 1 ? 1 : 0;
        map.tab_input_bits[a] = a % 5 == 0 ? 1 : 0;
    }
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2 || argc > 3) {
        std::fprintf(stderr, "usage: libmodbus_tcp_server PORT [LIFETIME_SECONDS]\n");
        return 2;
    }
    const int port = std::atoi(argv[1]);
    const unsigned lifetime = argc == 3 ? static_cast<unsigned>(std::atoi(argv[2])) : 45u;
    // SIGALRM's default action ends the process: the simplest way to bound its life.
    alarm(lifetime);

    modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
    if (ctx == nullptr) return fail("modbus_new_tcp");
    modbus_mapping_t* map = modbus_mapping_new(table_size, table_size, table_size, table_size);
    if (map == nullptr) return fail("modbus_mapping_new");
    preset(*map);

    int listener = modbus_tcp_listen(ctx, 1);
    if (listener < 0) return fail("modbus_tcp_listen");
    sockaddr_in bound{};
    socklen_t length = sizeof bound;
    if (getsockname(listener, reinterpret_cast<sockaddr*>(&bound), &length) != 0) return fail("getsockname");
    std::printf("listening on port %d\n", ntohs(bound.sin_port));
    std::fflush(stdout);

    // One client at a time: every loopwire command opens its own connection and closes it.
    for (;;) {
        if (modbus_tcp_accept(ctx, &listener) < 0) return fail("modbus_tcp_accept");
        uint8_t request[MODBUS_TCP_MAX_ADU_LENGTH];
        for (;;) {
            const int size = modbus_receive(ctx, request);
            if (size < 0) break;  // the client closed the connection (or sent garbage): next one
            if (size == 0) continue;  // a request libmodbus chose to ignore
            if (modbus_reply(ctx, request, size, map) < 0) break;
        }
        // Close only the connection's socket; the listener stays open for the next client.
        modbus_close(ctx);
    }
}
