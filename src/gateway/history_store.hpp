#pragma once
// The gateway's history: every change its polls find, and a heartbeat sample of every value each
// `heartbeat`, kept in an SQLite file (WAL mode) for `keep`, and asked for as downsampled series
// (gateway/history_source.hpp) by the HTTP API (docs/DESIGN.md, gateway).
//
// Threads: record() is what the value cache's callback calls on the poll threads; it only
// queues. One writer thread commits the queue in a transaction every `commit_interval` (0.5 s:
// a kill -9 loses at most the last second; WAL keeps every committed transaction whole, so the
// file is never corrupted by a crash), writes the heartbeats when due and deletes expired rows
// in small batches between commits. query() runs on the caller's thread on its own connection:
// WAL lets it read while the writer writes. The HTTP API asks on this thread (run_blocking), so
// that a long query or a slow historian never holds up the engine's loop it serves on.
//
// Schema (history_schema.cpp): `series` (device, parameter, unit) with integer ids; `samples`
// (series_id, t in ms since the epoch, value, text, status), WITHOUT ROWID with the key
// (series_id, t), so one parameter's range is one contiguous b-tree walk; `minutes`: per-minute
// min/max/sum/count of each series, kept as samples are written, which answers the buckets a
// minute wide or wider (30 days at 1 s: 43 200 rows read instead of 2.6 million).
//
// Forwarding (`forward`, [history] forward_to): every inserted sample is also noted in `outbox`
// in the same transaction, and a HistoryForwarder ships the outbox to PostgreSQL
// (gateway/history_forwarder.hpp); the file is then both the gateway's history and the buffer.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "common/result.hpp"
#include "gateway/history_forwarder.hpp"
#include "gateway/historian_reader.hpp"
#include "gateway/history_source.hpp"
#include "gateway/sqlite_database.hpp"
#include "gateway/value_cache.hpp"

namespace loopwire::gateway {

using SystemTime = std::chrono::system_clock::time_point;

struct HistoryOptions {
    std::filesystem::path database;
    std::chrono::seconds keep = std::chrono::hours(24 * 90);  // rows older than this are deleted
    std::chrono::milliseconds heartbeat{60000};  // every value written at least this often
    std::chrono::milliseconds commit_interval{500};
    // The clock heartbeats and retention run on: the time heartbeats are stamped with, and
    // the one retention counts back from. It is wall time (the samples' own stamps are), not
    // the steady common/clock.hpp; a test injects virtual time here. Empty: the system clock.
    std::function<SystemTime()> wall_clock;
    // false: no writer thread; the owner calls write_pending() (tests on virtual time, benches).
    bool writer_thread = true;
    // Failed commits (a full disk) and queue overflows; they are retried, not fatal.
    std::function<void(const std::string&)> log;
    // Changes held for the writer at most; beyond, new ones are counted as dropped and logged.
    std::size_t max_queued = 1'000'000;
    // [history] forward_to: each inserted sample is also noted in the file's outbox, in the same
    // transaction, and a forwarder ships the outbox to PostgreSQL (gateway/history_forwarder.hpp).
    std::optional<ForwardOptions> forward;
};

// A parameter the gateway polls: declared when the store opens, so that asking for its history
// before its first sample gives an empty series rather than "unknown".
struct HistorySeriesName {
    std::string device;
    std::string parameter;
    std::string unit;
};

class HistoryStore final : public HistorySource {
public:
    // Opens (or creates) the database; the error names the file and says what to do about it
    // (a missing or read-only folder, a file that is not a loopwire history database).
    static Result<std::unique_ptr<HistoryStore>> open(HistoryOptions options,
                                                      const std::vector<HistorySeriesName>& declared = {});
    ~HistoryStore() override;  // writes what is queued, then closes
    HistoryStore(const HistoryStore&) = delete;
    HistoryStore& operator=(const HistoryStore&) = delete;

    // Queues a change for the writer (the value cache's callback: quick, never blocks on the
    // database). Changes of a device's own status are not history and are ignored.
    void record(const ValueChange& change);

    // Commits what is queued, writes the heartbeats that are due and one retention batch: the
    // writer thread's step, called by the owner when there is no thread.
    Result<void> write_pending();
    // Deletes rows older than `keep` until none are left, in the same small batches.
    Result<void> enforce_retention();

    // This gateway's history from the file; another's (query.gateway) from the historian.
    Result<std::vector<HistorySeries>> query(const HistoryQuery& query) const override;
    std::uint64_t rows_written() const override;
    std::uint64_t dropped() const;  // changes refused because the queue was full
    std::optional<ForwardStats> forward_stats() const override;
    Result<std::vector<std::string>> historian_gateways() const override;
    // On the writer thread, before its next commit (at once when there is no thread).
    void run_blocking(std::function<void()> work) const override;
    HistoryForwarder* forwarder() { return forwarder_.get(); }  // null unless forwarding

    const std::filesystem::path& database() const { return options_.database; }

private:
    struct QueuedRow {
        std::string device;
        std::string parameter;
        std::string unit;
        std::optional<double> value;
        std::optional<std::string> text;
        std::optional<std::string> status;
        std::int64_t t = 0;
        bool heartbeat = false;  // a repeat of the last reading, stamped when it was written
    };
    struct Writer;
    struct Reader;

    explicit HistoryStore(HistoryOptions options);
    SystemTime wall_now() const;
    void run(std::stop_token stop);
    // The writer's steps; writer_mutex_ held.
    Result<std::int64_t> series_id(const std::string& device, const std::string& parameter, const std::string& unit);
    Result<void> insert_rows(const std::vector<QueuedRow>& rows, std::uint64_t& inserted);
    Result<std::uint64_t> commit(const std::vector<QueuedRow>& rows);  // the rows inserted
    void add_heartbeats(std::vector<QueuedRow>& batch);
    Result<std::int64_t> expire(sqlite::Statement& statement, std::int64_t series, std::int64_t before);
    Result<bool> retention_step(bool force);  // false: nothing was due
    void log(const std::string& message) const;
    Result<std::vector<HistorySeries>> historian_query(const HistoryQuery& query) const;
    HistoryQuery with_look_back(HistoryQuery query) const;  // look_back: twice the heartbeat

    HistoryOptions options_;
    std::unique_ptr<Writer> writer_;        // the writer's connection and state; its lock held
    mutable std::unique_ptr<Reader> reader_;  // query()'s connection; its own lock
    std::unique_ptr<HistorianReader> historian_;  // other gateways' history, when forwarding
    mutable std::mutex writer_mutex_;
    mutable std::mutex queue_mutex_;
    // The writer thread's wake-up: for errands (run_blocking), and to stop.
    mutable std::mutex errands_mutex_;
    mutable std::condition_variable_any errands_woken_;
    mutable std::vector<std::function<void()>> errands_;
    bool errands_thread_ = false;  // errands go to the writer thread (errands lock)
    std::vector<QueuedRow> queue_;
    // The last row of each series, for the heartbeats (writer's lock).
    std::map<std::pair<std::string, std::string>, QueuedRow> last_;
    std::uint64_t dropped_ = 0;               // queue lock
    std::uint64_t rows_written_ = 0;          // queue lock
    std::unique_ptr<HistoryForwarder> forwarder_;
    std::jthread thread_;  // last: stops and joins before the rest goes
};

// Whether a row with this status (none: "ok") holds what a poll read: a value, or a special state
// of one. A row that says nothing was read (no reply, its line down, stale, waiting, an error)
// does not: a heartbeat never repeats it, and it is never the value in force at a query's `from`.
bool holds_reading(const std::optional<std::string>& status);

// The rows of one parameter's buckets: how a series over [from, to] is cut into at most `points`
// buckets (exposed for the benchmark, which checks them against a plain GROUP BY).
struct BucketPlan {
    std::int64_t origin = 0;  // ms since the epoch: bucket i starts at origin + i * width
    std::int64_t width = 1;   // ms; a whole number of minutes when the minute table is used
    bool minutes = false;     // whole minutes inside [from, to] come from the minute table
};
BucketPlan plan_buckets(std::int64_t from, std::int64_t to, std::size_t points);
// The minutes (since the epoch) wholly inside [from, to] ms: first <= m < end; none when
// first >= end. The rest of the range is read from the samples.
struct MinuteSpan {
    std::int64_t first = 0;
    std::int64_t end = 0;
};
MinuteSpan whole_minutes(std::int64_t from, std::int64_t to);

}  // namespace loopwire::gateway
