#pragma once
// The gateway's history: every change its polls find, and a heartbeat sample of every value each
// `heartbeat`, kept in an SQLite file (WAL mode) for `keep`, and read back as downsampled series
// by the history reader (gateway/history_reader.hpp) on a connection of its own (docs/DESIGN.md,
// gateway).
//
// Threads: record() is what the value cache's callback calls on the poll threads; it only
// queues. One writer thread (start()) commits the queue in a transaction every `commit_interval`
// (0.5 s: a kill -9 loses at most the last second; WAL keeps every committed transaction whole,
// so the file is never corrupted by a crash), writes the heartbeats when due and deletes expired
// rows in small batches between commits. The writer only writes: queries are the reader's, on
// its own thread and connection, so a month of history asked for or a historian slow to answer
// never delays a commit (WAL lets the reader read while the writer writes).
//
// Schema (history_schema.cpp): `series` (device, parameter, unit) with integer ids; `samples`
// (series_id, t in ms since the epoch, value, text, status), WITHOUT ROWID with the key
// (series_id, t), so one parameter's range is one contiguous b-tree walk; `minutes`: per-minute
// min/max/sum/count of each series, kept as samples are written, which answers the buckets a
// minute wide or wider (30 days at 1 s: 43 200 rows read instead of 2.6 million).
//
// Forwarding ([history] forward_to, `outbox`): every inserted sample is also noted in `outbox` in
// the same transaction; a HistoryForwarder beside the store (gateway/history_forwarder.hpp, made
// by the gateway) ships the outbox to PostgreSQL, so the file is both the gateway's history and
// the buffer. The store only tells it, through on_outbox(), how many rows each commit noted.
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
#include "gateway/sqlite_database.hpp"
#include "gateway/value_cache.hpp"
#include "gateway/write_audit.hpp"

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
    // Failed commits (a full disk) and queue overflows; they are retried, not fatal.
    std::function<void(const std::string&)> log;
    // Changes held for the writer at most; beyond, new ones are counted as dropped and logged.
    std::size_t max_queued = 1'000'000;
    // [history] forward_to: each inserted sample is also noted in the file's outbox, in the same
    // transaction, for the forwarder that ships it to PostgreSQL (gateway/history_forwarder.hpp).
    bool outbox = false;
};

// A commit noted `rows` more in the outbox, the first stamped `first_t` (ms since the epoch).
using OutboxNoted = std::function<void(std::uint64_t rows, std::int64_t first_t)>;

// A parameter the gateway polls: declared when the store opens, so that asking for its history
// before its first sample gives an empty series rather than "unknown".
struct HistorySeriesName {
    std::string device;
    std::string parameter;
    std::string unit;
};

class HistoryStore final {
public:
    // Opens (or creates) the database; the error names the file and says what to do about it
    // (a missing or read-only folder, a file that is not a loopwire history database). No writer
    // thread yet: the owner calls write_pending() (tests on virtual time, benches), or start().
    static Result<std::unique_ptr<HistoryStore>> open(HistoryOptions options,
                                                      const std::vector<HistorySeriesName>& declared = {});
    ~HistoryStore();  // stops the writer thread, writes what is queued, then closes
    HistoryStore(const HistoryStore&) = delete;
    HistoryStore& operator=(const HistoryStore&) = delete;

    // Who hears of the rows each commit notes in the outbox (the forwarder): given before start(),
    // or, without a writer thread, between the owner's writes.
    void on_outbox(OutboxNoted noted) { outbox_noted_ = std::move(noted); }
    // Run by the writer thread after each of its commits, and once more as the store closes: the
    // writer of another table of the file (the alarm journal) that then needs no thread of its
    // own. Given before start(); it must outlive the store.
    void also_write(std::function<void()> step) { also_write_ = std::move(step); }
    // Starts the writer thread (named lw-history); once at most.
    void start();

    // Queues a change for the writer (the value cache's callback: quick, never blocks on the
    // database). Changes of a device's own status are not history and are ignored.
    void record(const ValueChange& change);
    // Queues a write's audit record for the writer (WriteAudit's: quick, never blocks), committed
    // with the next batch into the `writes` table.
    void record_write(const AuditRecord& record);
    // Queues `job` for the writer: run in a transaction of its own at the next commit, after the
    // changes queued before it, in the order given (quick, never blocks on the database). For a
    // part of the gateway that keeps its own rows in the file (Sparkplug's store and forward,
    // gateway/sparkplug/sparkplug_pending.hpp). A job that fails is logged and retried.
    using WriterJob = std::function<Result<void>(sqlite::Connection&)>;
    void run_in_writer(WriterJob job);

    // Commits what is queued, writes the heartbeats that are due and one retention batch: the
    // writer thread's step, called by the owner when there is no thread (never beside it).
    Result<void> write_pending();
    // Deletes rows older than `keep` until none are left, in the same small batches (as
    // write_pending(): without a writer thread).
    Result<void> enforce_retention();

    std::uint64_t rows_written() const;  // committed since the store opened (GET /metrics)
    std::uint64_t dropped() const;  // changes refused because the queue was full

    const std::filesystem::path& database() const { return options_.database; }
    std::chrono::milliseconds heartbeat() const { return options_.heartbeat; }

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

    explicit HistoryStore(HistoryOptions options);
    SystemTime wall_now() const;
    void run(std::stop_token stop);
    // The writer's steps: on the writer thread, or the owner's without one.
    Result<std::int64_t> series_id(const std::string& device, const std::string& parameter, const std::string& unit);
    Result<void> insert_rows(const std::vector<QueuedRow>& rows, std::uint64_t& inserted);
    Result<std::uint64_t> commit(const std::vector<QueuedRow>& rows);  // the rows inserted
    Result<void> commit_writes(const std::vector<AuditRecord>& writes);
    Result<void> run_jobs(std::vector<WriterJob>& jobs);  // those not done are left in `jobs`
    void add_heartbeats(std::vector<QueuedRow>& batch);
    Result<std::int64_t> expire(sqlite::Statement& statement, std::int64_t series, std::int64_t before);
    Result<bool> retention_step(bool force);  // false: nothing was due
    void log(const std::string& message) const;

    HistoryOptions options_;
    std::unique_ptr<Writer> writer_;  // the writer's connection and state
    OutboxNoted outbox_noted_;
    std::function<void()> also_write_;
    // The queue of changes to the writer thread (and its wake-up to stop); the one lock the poll
    // threads share with the writer, held only to swap the queue, never across SQLite.
    mutable std::mutex queue_mutex_;
    std::condition_variable_any stop_woken_;
    std::vector<QueuedRow> queue_;
    std::vector<AuditRecord> writes_queue_;
    std::vector<WriterJob> jobs_;
    // The last row of each series, for the heartbeats (the writer's).
    std::map<std::pair<std::string, std::string>, QueuedRow> last_;
    std::uint64_t dropped_ = 0;               // queue lock
    std::uint64_t rows_written_ = 0;          // queue lock
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
