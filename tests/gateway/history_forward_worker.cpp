// For history_forward_test's crash test: opens the history named on the command line with its
// forwarder thread shipping the outbox to the PostgreSQL connection string given, and waits to
// be killed.
#include <cstdio>
#include <thread>

#include "support/history_parts.hpp"

int main(int argc, char** argv) {
    using namespace loopwire::gateway;
    if (argc != 3) {
        std::fprintf(stderr, "usage: history_forward_worker DATABASE CONNINFO\n");
        return 2;
    }
    loopwire::testing::HistoryPartsOptions options;
    options.database = argv[1];
    options.heartbeat = std::chrono::hours(24);
    // The test's rows are stamped in 2026-01 whatever today is: none may expire here.
    options.keep = std::chrono::hours(24 * 365 * 100);
    ForwardOptions forward;
    forward.conninfo = argv[2];
    forward.gateway = "plant1";
    forward.batch_rows = 2000;  // many batches: the kill lands between two or inside one
    options.forward = forward;
    options.log = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
    auto history = loopwire::testing::HistoryParts::open(options);
    if (!history) {
        std::fprintf(stderr, "%s\n", history.error().message.c_str());
        return 1;
    }
    (*history)->store->start();
    for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
}
