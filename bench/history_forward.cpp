// The history's forwarding to PostgreSQL (bench/history_forward.sh runs it against a server it
// starts): fills a local history file with ROWS samples over 50 parameters, as the store's
// writer would (each noted in the outbox), writes the same rows as CSV for psql's \copy, then
// times the forwarder shipping the whole outbox. Prints "forwarded N rows in S s".
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include <fmt/format.h>

#include "gateway/history_forwarder.hpp"
#include "gateway/history_store.hpp"

namespace {

using namespace loopwire::gateway;
constexpr int parameters = 50;
const SystemTime start = SystemTime(std::chrono::seconds(1767225600));  // 2026-01-01

ValueChange sample(long long i) {
    ValueChange change;
    change.device = "bench";
    change.parameter = fmt::format("p{}", i % parameters);
    change.unit = "°C";
    change.status = "ok";
    change.value = loopwire::device::EngineeringValue{static_cast<double>(i % 1000) / 10.0, "ok", 0, "°C"};
    change.sampled = start + std::chrono::seconds(i / parameters);
    return change;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 5) {
        std::fprintf(stderr, "usage: history_forward DATABASE CONNINFO ROWS CSV\n");
        return 2;
    }
    const long long rows = std::atoll(argv[3]);
    HistoryOptions options;
    options.database = argv[1];
    options.heartbeat = std::chrono::hours(24);
    options.keep = std::chrono::hours(24 * 365 * 100);
    options.max_queued = 2'000'000;
    options.wall_clock = [] { return start; };
    ForwardOptions forward;
    forward.conninfo = argv[2];
    forward.gateway = "bench";
    forward.thread = false;
    if (const char* batch = std::getenv("LOOPWIRE_FORWARD_BATCH")) forward.batch_rows = static_cast<std::size_t>(std::atoll(batch));
    options.outbox = true;
    auto store = HistoryStore::open(options);
    if (!store) {
        std::fprintf(stderr, "%s\n", store.error().message.c_str());
        return 1;
    }
    // The \copy peer's rows: the same series (numbered as the local file numbers them), times
    // and values.
    std::ofstream csv(argv[4]);
    for (long long i = 0; i < rows; ++i) {
        const ValueChange change = sample(i);
        (*store)->record(change);
        csv << (i % parameters) + 1 << ','
            << std::chrono::duration_cast<std::chrono::milliseconds>(change.sampled.time_since_epoch()).count() << ','
            << fmt::format("{}", std::get<double>(change.value->value)) << ",,\n";
        if (i % 100000 == 99999 && !(*store)->write_pending()) return 1;
    }
    if (!(*store)->write_pending()) return 1;
    csv.close();
    // The forwarder beside the store, as the gateway makes it, once the rows are committed.
    auto forwarder = HistoryForwarder::start(options.database, forward, options.keep, options.wall_clock, {});
    if (!forwarder) {
        std::fprintf(stderr, "%s\n", forwarder.error().message.c_str());
        return 1;
    }
    // The historian's tables made beforehand, as the \copy peer's table is: the time is the
    // rows' (and a connect's, as psql's includes one).
    if (auto made = check_forward_target(forward); !made) {
        std::fprintf(stderr, "%s\n", made.error().message.c_str());
        return 1;
    }
    const auto began = std::chrono::steady_clock::now();
    auto shipped = (*forwarder)->forward_pending();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count();
    if (!shipped) {
        std::fprintf(stderr, "%s\n", shipped.error().message.c_str());
        return 1;
    }
    std::printf("forwarded %llu rows in %.3f s\n", static_cast<unsigned long long>(*shipped), seconds);
    return 0;
}
