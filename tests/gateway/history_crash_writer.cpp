// For history_store_test's crash test: records a value every millisecond into the history
// database named on the command line, with the store's own writer thread committing, and
// prints "N STEADY_MS" after every tenth (values 0..N recorded by then) until it is killed.
#include <chrono>
#include <cstdio>
#include <thread>

#include "gateway/history_store.hpp"

int main(int argc, char** argv) {
    using namespace loopwire::gateway;
    using namespace std::chrono_literals;
    if (argc != 2) {
        std::fprintf(stderr, "usage: history_crash_writer DATABASE\n");
        return 2;
    }
    HistoryOptions options;
    options.database = argv[1];
    auto store = HistoryStore::open(options);
    if (!store) {
        std::fprintf(stderr, "%s\n", store.error().message.c_str());
        return 1;
    }
    (*store)->start();
    const auto start = std::chrono::system_clock::now();
    for (long long n = 0;; ++n) {
        ValueChange change;
        change.device = "oven1";
        change.parameter = "measured_value";
        change.unit = "°C";
        change.status = "ok";
        change.value = loopwire::device::EngineeringValue{static_cast<double>(n), "ok", 0, "°C"};
        change.sampled = start + std::chrono::milliseconds(n);
        (*store)->record(change);
        if (n % 10 == 0) {
            const auto now = std::chrono::steady_clock::now().time_since_epoch();
            std::printf("%lld %lld\n", n, static_cast<long long>(std::chrono::duration_cast<std::chrono::milliseconds>(now).count()));
            std::fflush(stdout);
        }
        std::this_thread::sleep_for(1ms);
    }
}
