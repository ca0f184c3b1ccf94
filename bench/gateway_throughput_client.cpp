// Many Modbus/TCP clients at once, for gateway_throughput.sh: CONNECTIONS libmodbus masters,
// one thread and one connection each, read the same holding registers of one unit for a fixed
// time. Each waits for its reply before it sends again (what a SCADA client does), so the load
// on a gateway is CONNECTIONS requests outstanding, queued on the line behind it.
//
// Usage: gateway_throughput_client HOST PORT SECONDS CONNECTIONS UNIT ADDRESS COUNT [count-failures]
// Every connection first gets one untimed request answered (it proves the path and pays for the
// first-time costs); then all start together and count the replies that arrive within SECONDS.
// Prints on stdout:
//   requests/s: R                   replies within the window / the window
//   requests: N, seconds: S, mean latency: L ms, max latency: M ms
//   requests sent in all: T         warm-up and the ones that ended after the window included
//                                   (what a gateway's line counters saw from these clients)
// Exit 1 if any request fails (an exception reply or no reply): a throughput built on errors
// means nothing. With count-failures (a line whose faults are what is measured) a failed request
// is counted and the client goes on; it then also prints
//   requests failed: F              within the window, not in the requests/s
#include <modbus/modbus.h>

#include <algorithm>
#include <atomic>
#include <barrier>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

struct Arguments {
    std::string host;
    int port = 0;
    double seconds = 0;
    int connections = 0;
    int unit = 0;
    int address = 0;
    int count = 0;
    bool count_failures = false;
};

struct Tally {
    long answered_in_window = 0;
    long sent = 0;
    long failed_in_window = 0;
    double latency_sum = 0;  // seconds, over the replies within the window
    double latency_max = 0;
    bool failed = false;
};

// Run once, on the last client to reach the start line, before any is released: the window
// starts when every client is ready.
struct MarkStart {
    Clock::time_point* at;
    void operator()() noexcept { *at = Clock::now(); }
};
using StartLine = std::barrier<MarkStart>;

bool parse_int(const char* text, int low, int high, int& out) {
    char* end = nullptr;
    const long value = std::strtol(text, &end, 10);
    if (end == text || *end != '\0' || value < low || value > high) return false;
    out = static_cast<int>(value);
    return true;
}

bool parse(int argc, char** argv, Arguments& args) {
    if (argc != 8 && argc != 9) return false;
    if (argc == 9) {
        if (std::string(argv[8]) != "count-failures") return false;
        args.count_failures = true;
    }
    args.host = argv[1];
    char* end = nullptr;
    args.seconds = std::strtod(argv[3], &end);
    return parse_int(argv[2], 1, 65535, args.port) && end != argv[3] && *end == '\0' && args.seconds > 0 &&
           parse_int(argv[4], 1, 1000, args.connections) && parse_int(argv[5], 0, 255, args.unit) &&
           parse_int(argv[6], 0, 65535, args.address) && parse_int(argv[7], 1, 125, args.count);
}

// One client: connect, one untimed request, wait for the others, then read until the window ends.
void run_client(const Arguments& args, int index, StartLine& start_line, std::atomic<bool>& abort,
                Clock::time_point& window_start, Tally& tally) {
    modbus_t* ctx = modbus_new_tcp(args.host.c_str(), args.port);
    bool ready = ctx != nullptr && modbus_set_slave(ctx, args.unit) == 0;
    // Generous: behind a gateway a request waits for every other client's turn on a slow line
    // (20 clients x ~21 ms at 19200 baud); a timeout here would be a failure, not a figure.
    if (ready) ready = modbus_set_response_timeout(ctx, 10, 0) == 0 && modbus_connect(ctx) == 0;
    if (!ready) std::fprintf(stderr, "gateway_throughput_client: client %d cannot connect: %s\n", index, modbus_strerror(errno));
    std::vector<uint16_t> values(static_cast<std::size_t>(args.count));
    auto read_once = [&]() {
        ++tally.sent;
        if (modbus_read_registers(ctx, args.address, args.count, values.data()) == args.count) return true;
        std::fprintf(stderr, "gateway_throughput_client: client %d: request %ld failed: %s\n", index, tally.sent,
                     modbus_strerror(errno));
        return false;
    };
    // With count-failures a first request that fails is one of the faults measured, not a path
    // that does not work: only a connection that cannot be made stops the run.
    if (ready) ready = read_once() || args.count_failures;
    if (!ready) {
        tally.failed = true;
        abort = true;
    }
    start_line.arrive_and_wait();  // everyone has connected (or failed); window_start is set
    const auto deadline = window_start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(args.seconds));
    while (ready && !abort) {
        const auto sent_at = Clock::now();
        if (sent_at >= deadline) break;
        const bool answered = read_once();
        if (!answered && !args.count_failures) {
            tally.failed = true;
            abort = true;
            break;
        }
        const auto answered_at = Clock::now();
        if (answered_at > deadline) break;  // ended after the window: not counted
        if (!answered) {
            ++tally.failed_in_window;
            modbus_flush(ctx);  // a late answer to it must not be read as the next one's
            continue;
        }
        const double latency = std::chrono::duration<double>(answered_at - sent_at).count();
        ++tally.answered_in_window;
        tally.latency_sum += latency;
        tally.latency_max = std::max(tally.latency_max, latency);
    }
    if (ctx != nullptr) {
        modbus_close(ctx);
        modbus_free(ctx);
    }
}

}  // namespace

int main(int argc, char** argv) {
    Arguments args;
    if (!parse(argc, argv, args)) {
        std::fprintf(stderr, "usage: gateway_throughput_client HOST PORT SECONDS CONNECTIONS UNIT ADDRESS COUNT [count-failures]\n"
                             "  (SECONDS > 0, CONNECTIONS 1..1000, UNIT 0..255, ADDRESS 0..65535, COUNT 1..125)\n");
        return 2;
    }
    std::vector<Tally> tallies(static_cast<std::size_t>(args.connections));
    std::atomic<bool> abort{false};
    Clock::time_point window_start;
    StartLine start_line(args.connections, MarkStart{&window_start});
    std::vector<std::thread> clients;
    for (int i = 0; i < args.connections; ++i) {
        clients.emplace_back(run_client, std::cref(args), i, std::ref(start_line), std::ref(abort), std::ref(window_start),
                             std::ref(tallies[static_cast<std::size_t>(i)]));
    }
    for (auto& client : clients) client.join();

    Tally total;
    for (const auto& tally : tallies) {
        total.answered_in_window += tally.answered_in_window;
        total.sent += tally.sent;
        total.failed_in_window += tally.failed_in_window;
        total.latency_sum += tally.latency_sum;
        total.latency_max = std::max(total.latency_max, tally.latency_max);
        total.failed = total.failed || tally.failed;
    }
    if (total.failed) return 1;
    if (total.answered_in_window == 0) {
        std::fprintf(stderr, "gateway_throughput_client: no reply within the %.3f s window\n", args.seconds);
        return 1;
    }
    const double replies = static_cast<double>(total.answered_in_window);
    std::printf("requests: %ld, seconds: %.3f, mean latency: %.2f ms, max latency: %.2f ms\n", total.answered_in_window,
                args.seconds, 1e3 * total.latency_sum / replies, 1e3 * total.latency_max);
    std::printf("requests sent in all: %ld\n", total.sent);
    if (args.count_failures) std::printf("requests failed: %ld\n", total.failed_in_window);
    std::printf("requests/s: %.1f\n", replies / args.seconds);
    return 0;
}
