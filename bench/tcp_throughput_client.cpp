// Loopback Modbus/TCP request/response throughput, measured with libmodbus as the master so
// that loopwire's simulator and libmodbus's own slave are judged by the same client.
//
// Usage: tcp_throughput_client HOST PORT REQUESTS [UNIT]
// Sends REQUESTS "read 10 holding registers" (FC3) requests one after another, each waiting for
// its reply (a master on one connection, as in practice), after a short untimed warm-up.
// Prints "requests/s: R" (and the details) on stdout. Exit 1 on any failed request.
#include <modbus/modbus.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>

namespace {

constexpr int registers_per_request = 10;
constexpr long warm_up_requests = 200;

bool read_once(modbus_t* ctx, long index) {
    uint16_t values[registers_per_request];
    if (modbus_read_registers(ctx, 0, registers_per_request, values) == registers_per_request) return true;
    std::fprintf(stderr, "tcp_throughput_client: request %ld failed: %s\n", index, modbus_strerror(errno));
    return false;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 4 || argc > 5) {
        std::fprintf(stderr, "usage: tcp_throughput_client HOST PORT REQUESTS [UNIT]\n");
        return 2;
    }
    const long requests = std::atol(argv[3]);
    if (requests <= 0) {
        std::fprintf(stderr, "tcp_throughput_client: REQUESTS must be a positive number, not '%s'\n", argv[3]);
        return 2;
    }
    modbus_t* ctx = modbus_new_tcp(argv[1], std::atoi(argv[2]));
    if (ctx == nullptr || modbus_set_slave(ctx, argc == 5 ? std::atoi(argv[4]) : 1) != 0) {
        std::fprintf(stderr, "tcp_throughput_client: bad arguments: %s\n", modbus_strerror(errno));
        return 2;
    }
    modbus_set_response_timeout(ctx, 2, 0);
    if (modbus_connect(ctx) != 0) {
        std::fprintf(stderr, "tcp_throughput_client: cannot connect to %s:%s: %s\n", argv[1], argv[2], modbus_strerror(errno));
        modbus_free(ctx);
        return 1;
    }
    int status = 0;
    // Untimed warm-up: the first requests pay for page faults and cold caches on both sides.
    for (long i = 0; i < warm_up_requests && status == 0; ++i) status = read_once(ctx, i) ? 0 : 1;
    const auto start = std::chrono::steady_clock::now();
    for (long i = 0; i < requests && status == 0; ++i) status = read_once(ctx, i) ? 0 : 1;
    const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start;
    modbus_close(ctx);
    modbus_free(ctx);
    if (status != 0) return status;
    std::printf("requests: %ld, seconds: %.3f, mean latency: %.1f us\n", requests, elapsed.count(),
                1e6 * elapsed.count() / static_cast<double>(requests));
    std::printf("requests/s: %.0f\n", static_cast<double>(requests) / elapsed.count());
    return 0;
}
