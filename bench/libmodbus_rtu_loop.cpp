// A plain RTU master alone on a line, for serial_line_share.sh: libmodbus reading the same holding
// registers of one unit again and again for a fixed time. libmodbus takes a reply as whole when
// the bytes its function code calls for have come (it waits for no silence after them, and holds
// no reply to see what follows); this loop then keeps the 3.5 characters of silence Modbus asks
// before the next request (Modbus over serial line V1.02, 2.5.1.1), which libmodbus itself does
// not. So it is what a line gives a master that keeps the rules and loses no time of its own: the
// reference the gateway's figure is held against.
//
// Usage: libmodbus_rtu_loop DEVICE BAUD SECONDS UNIT ADDRESS COUNT        (8N1)
// Prints on stdout:
//   requests: N, failed: F, seconds: S    F = timeouts, CRC errors, exception replies
//   requests/s: R                         replies within the window / the window
// Exit 1 if no request was answered, 2 on bad arguments or a port that cannot be opened.
#include <modbus/modbus.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <thread>
#include <vector>

namespace {

using WallClock = std::chrono::steady_clock;

bool parse_long(const char* text, long low, long high, long& out) {
    char* end = nullptr;
    out = std::strtol(text, &end, 10);
    return end != text && *end == '\0' && out >= low && out <= high;
}

}  // namespace

int main(int argc, char** argv) {
    long baud = 0;
    long unit = 0;
    long address = 0;
    long count = 0;
    char* end = nullptr;
    const double seconds = argc == 7 ? std::strtod(argv[3], &end) : 0.0;
    if (argc != 7 || end == argv[3] || *end != '\0' || seconds <= 0 || !parse_long(argv[2], 300, 4000000, baud) ||
        !parse_long(argv[4], 1, 247, unit) || !parse_long(argv[5], 0, 65535, address) || !parse_long(argv[6], 1, 125, count)) {
        std::fprintf(stderr, "usage: libmodbus_rtu_loop DEVICE BAUD SECONDS UNIT ADDRESS COUNT\n"
                             "  (8N1; SECONDS > 0, UNIT 1..247, ADDRESS 0..65535, COUNT 1..125)\n");
        return 2;
    }
    modbus_t* ctx = modbus_new_rtu(argv[1], static_cast<int>(baud), 'N', 8, 1);
    if (ctx == nullptr || modbus_set_slave(ctx, static_cast<int>(unit)) != 0 || modbus_set_response_timeout(ctx, 1, 0) != 0 ||
        modbus_connect(ctx) != 0) {
        std::fprintf(stderr, "libmodbus_rtu_loop: cannot open %s: %s\n", argv[1], modbus_strerror(errno));
        if (ctx != nullptr) modbus_free(ctx);
        return 2;
    }
    // 3.5 characters of 10 bits; above 19200 baud the fixed 1.75 ms.
    const auto silence = std::chrono::microseconds(baud > 19200 ? 1750 : 35'000'000 / baud);
    std::vector<uint16_t> values(static_cast<std::size_t>(count));
    auto read_once = [&] {
        const bool answered = modbus_read_registers(ctx, static_cast<int>(address), static_cast<int>(count), values.data()) == count;
        const int error = errno;
        std::this_thread::sleep_for(silence);
        if (!answered) modbus_flush(ctx);  // what came of a broken reply is not the next one's
        errno = error;
        return answered;
    };
    if (!read_once()) std::fprintf(stderr, "libmodbus_rtu_loop: first request: %s\n", modbus_strerror(errno));

    long answered = 0;
    long failed = 0;
    std::map<std::string, long> failures;  // message -> how often
    const auto deadline = WallClock::now() + std::chrono::duration_cast<WallClock::duration>(std::chrono::duration<double>(seconds));
    while (WallClock::now() < deadline) {
        const bool ok = read_once();
        const int error = errno;
        if (WallClock::now() > deadline) break;  // ended after the window: not counted
        if (ok) {
            ++answered;
        } else {
            ++failed;
            ++failures[modbus_strerror(error)];
        }
    }
    modbus_close(ctx);
    modbus_free(ctx);
    for (const auto& [message, times] : failures) std::fprintf(stderr, "libmodbus_rtu_loop: %ld x %s\n", times, message.c_str());
    std::printf("requests: %ld, failed: %ld, seconds: %.3f\n", answered, failed, seconds);
    std::printf("requests/s: %.1f\n", static_cast<double>(answered) / seconds);
    return answered > 0 ? 0 : 1;
}
