// The historian's query (bench/history_query_pg.sh runs it against a server it starts): loads
// DAYS days of one sample a second of one series into the PostgreSQL historian's tables, with
// the per-minute rollup the forwarder keeps, then times the 500-bucket query of the whole range
// as /api/history?gateway= asks it. Prints the load and the query's times, checks that the
// buckets hold every sample, and times the same buckets grouped from the samples alone.
//
// The rows are made by the server (generate_series) rather than forwarded: the figure is the
// query's, and the forwarder's rollup is proven by the tests (history_forward_test.cpp).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "gateway/history_store.hpp"
#include "gateway/postgres_history_query.hpp"
#include "gateway/postgres_history_schema.hpp"

namespace {

using namespace loopwire::gateway;
constexpr std::int64_t start_ms = 1767225600000;  // 2026-01-01T00:00:00Z
constexpr int repeats = 5;

// Samples, a second apart, with a value that moves (a slow wave and a fast ripple), then the
// minutes from them as the forwarder's statement computes them.
loopwire::Result<void> load(postgres::Connection& db, std::int64_t days) {
    std::vector<std::int64_t> partitions;
    for (std::int64_t day = 0; day < days; ++day) partitions.push_back(postgres_history::day_of(start_ms) + day);
    if (auto made = postgres_history::ensure_partitions(db, partitions); !made) return made.error();
    if (auto added = db.run("INSERT INTO loopwire_series(gateway, device, parameter, unit) VALUES ('bench', 'oven1', 'temperature', '°C')");
        !added) {
        return added.error();
    }
    const std::string samples = fmt::format(
        "INSERT INTO loopwire_samples(series_id, t, value, status) "
        "SELECT 1, {0} + s * 1000, 50 + 20 * sin(s / 3600.0) + (s % 7), 'ok' FROM generate_series(0::bigint, {1} - 1) s",
        start_ms, days * 86400);
    if (auto added = db.run(samples); !added) return added.error();
    if (auto added = db.run("INSERT INTO loopwire_minutes(series_id, minute, lo, hi, total, n) "
                            "SELECT series_id, floor(t / 60000.0)::bigint, min(value), max(value), sum(value), count(*) "
                            "FROM loopwire_samples GROUP BY 1, 2");
        !added) {
        return added.error();
    }
    return db.run("VACUUM ANALYZE");  // as autovacuum would have, long before a month is queried
}

double milliseconds_since(std::chrono::steady_clock::time_point began) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - began).count();
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2 || argc > 3) {
        std::fprintf(stderr, "usage: history_query_pg CONNINFO [DAYS]\n");
        return 2;
    }
    const std::int64_t days = argc == 3 ? std::atoll(argv[2]) : 30;
    auto db = postgres::Connection::connect(argv[1], std::nullopt, 30);
    if (!db) {
        std::fprintf(stderr, "%s\n", db.error().message.c_str());
        return 1;
    }
    const auto loading = std::chrono::steady_clock::now();
    loopwire::Result<void> loaded = postgres_history::migrate(*db);
    if (loaded) loaded = load(*db, days);
    if (!loaded) {
        std::fprintf(stderr, "%s\n", loaded.error().message.c_str());
        return 1;
    }
    std::printf("loaded %lld samples (%lld days at 1 s) in %.1f s\n", static_cast<long long>(days * 86400),
                static_cast<long long>(days), milliseconds_since(loading) / 1000.0);
    HistoryQuery query;
    query.device = "oven1";
    query.from = std::chrono::system_clock::time_point(std::chrono::milliseconds(start_ms));
    query.to = query.from + std::chrono::hours(24 * days) - std::chrono::milliseconds(1);
    query.points = 500;
    std::vector<double> times;
    for (int i = 0; i < repeats; ++i) {
        const auto began = std::chrono::steady_clock::now();
        auto answer = postgres_history::run_query(*db, "bench", query);
        times.push_back(milliseconds_since(began));
        if (!answer) {
            std::fprintf(stderr, "%s\n", answer.error().message.c_str());
            return 1;
        }
        std::size_t samples = 0;
        for (const auto& bucket : answer->front().buckets) samples += bucket.count;
        if (answer->front().buckets.size() > 500 || samples != static_cast<std::size_t>(days * 86400)) {
            std::fprintf(stderr, "wrong answer: %zu buckets holding %zu samples\n", answer->front().buckets.size(), samples);
            return 1;
        }
    }
    std::sort(times.begin(), times.end());
    std::printf("500 buckets of %lld days at 1 s from the historian: %.1f ms (median of %d; best %.1f ms; goal < 200 ms)\n",
                static_cast<long long>(days), times[repeats / 2], repeats, times.front());
    // The peer: the same buckets grouped from the samples alone, what the rollup saves.
    const auto began = std::chrono::steady_clock::now();
    auto raw = db->execute(fmt::format("SELECT (t - {0}) / {1}, min(value), max(value), avg(value), count(*) FROM loopwire_samples "
                                       "WHERE series_id = 1 AND t >= {0} AND t < {0} + {2} GROUP BY 1",
                                       start_ms, plan_buckets(start_ms, start_ms + days * 86400000 - 1, 500).width, days * 86400000));
    if (!raw) {
        std::fprintf(stderr, "%s\n", raw.error().message.c_str());
        return 1;
    }
    std::printf("the same buckets grouped from the samples alone: %.1f ms\n", milliseconds_since(began));
    return 0;
}
