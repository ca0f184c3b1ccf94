#pragma once
// Store and forward of the history to a PostgreSQL historian ([history] forward_to) that many
// gateways share (gateway/postgres_history_schema.hpp has its tables).
//
// The SQLite file stays the gateway's own history and its buffer: the store's writer notes each
// sample it inserts in the file's `outbox` table in the same transaction (history_store.cpp), so
// a row is either committed and waiting, or not there at all. This forwarder, on its own thread
// and its own connection to the file, reads the outbox in order, ships a batch in one transaction
// (COPY; idempotent on (series, t): a batch sent again skips the rows already there), and only
// then deletes what it shipped from the outbox. A kill between the two sends the batch again;
// nothing is doubled.
//
// Every row is filed under its own gateway's series. The historian's series ids are learnt per
// connection, and each batch's transaction first finds (and locks) the series rows it files
// under, by id and by gateway, device, parameter and unit: a batch whose ids no longer name
// those (the tables dropped and made again under a running gateway, so that an id learnt before
// now names another gateway's series) is not sent; the ids are learnt again, missing tables are
// made again, and the batch is tried once more at once, as after any failed batch on a working
// connection (a table dropped: "relation does not exist"). A row counts as forwarded only once
// PostgreSQL has committed it under its own series.
//
// PostgreSQL down, slow or refusing never reaches polling or the store's writer: the forwarder
// alone waits, retrying with back-off (retry_first doubling to retry_max), logging one line when
// an outage starts and one when it ends, not one per retry.
//
// Stopping waits for the round under way: a connect is bounded by connect_timeout_seconds and a
// statement by the session's statement_timeout (120 s), but a server that stops answering in
// the middle of a statement without closing its socket (a frozen host) holds the stop until the
// kernel gives up on the connection.
//
// The audit of writes and reloads (the file's `writes` table) goes to the historian's
// loopwire_writes after the samples, in the same rounds: the rows after the last (t, id) the
// historian holds for this gateway, asked of it once per connection (and after a failed batch)
// and followed here after; a row sent twice (a crash between the historian's commit and the
// next round) is there once. The file keeps the rows for `keep` whether shipped or not, so a
// gateway that starts forwarding later ships the audit it has.
//
// Retention: a sample older than `keep` is deleted from the file whether or not it was shipped
// (the local disk is the bound); when the forwarder meets such an outbox row it drops it and
// logs how many it dropped. The historian's own day partitions are dropped after `keep` too.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <tuple>
#include <utility>

#include "common/result.hpp"
#include "gateway/forward_batch.hpp"
#include "gateway/history_outbox.hpp"
#include "gateway/history_source.hpp"
#include "gateway/postgres_database.hpp"

namespace loopwire::gateway {

struct ForwardOptions {
    std::string conninfo;                 // [history] forward_to: a postgresql:// URL or key=value pairs
    std::optional<std::string> password;  // from password_file; none: the URL's, PGPASSFILE's or none
    std::string gateway;                  // [gateway] name, part of every series in the historian
    bool thread = true;                   // false: the owner calls forward_pending() (tests)
    std::size_t batch_rows = 20000;       // rows one transaction ships at most
    std::chrono::milliseconds idle_poll{500};    // how often an empty outbox is looked at again
    std::chrono::milliseconds retry_first{1000};  // the first wait after a failure, doubled each time
    std::chrono::milliseconds retry_max{30000};
    int connect_timeout_seconds = 10;
};

class HistoryForwarder {
public:
    using Clock = std::function<std::chrono::system_clock::time_point()>;
    // Opens its own connection to the store's file (already set up by the store); connects to
    // PostgreSQL only on its thread or in forward_pending(), never here.
    static Result<std::unique_ptr<HistoryForwarder>> start(const std::filesystem::path& database, ForwardOptions options,
                                                           std::chrono::seconds keep, Clock wall_clock,
                                                           std::function<void(const std::string&)> log);
    ~HistoryForwarder();
    HistoryForwarder(const HistoryForwarder&) = delete;
    HistoryForwarder& operator=(const HistoryForwarder&) = delete;

    // Connects if needed and ships until the outbox is empty: the thread's step. The rows shipped.
    Result<std::uint64_t> forward_pending();
    // Drops the historian's day partitions older than `keep` (the thread does it hourly).
    Result<void> drop_expired_partitions();
    ForwardStats stats() const;
    // The store's writer committed `rows` more into the outbox, the first stamped `first_t`:
    // keeps /metrics current between the forwarder's rounds without reading the file.
    void queued(std::uint64_t rows, std::int64_t first_t);

private:
    HistoryForwarder(ForwardOptions options, std::chrono::seconds keep, Clock wall_clock,
                     std::function<void(const std::string&)> log);
    // A batch as the historian takes it, and its series as verify_series checks them.
    struct HistorianBatch {
        ForwardBatch rows;
        postgres::Parameters series_check;  // gateway, then the arrays of ids, devices, parameters, units
        std::size_t series = 0;             // how many series the rows are filed under
    };
    void run(std::stop_token stop);
    Result<void> connect();
    Result<void> forward_all();
    Result<HistorianBatch> for_historian(const OutboxBatch& batch);
    Result<const SeriesNames*> local_names(std::int64_t series);
    Result<void> learn_series(const OutboxBatch& batch);
    Result<void> verified(const HistorianBatch& batch);
    Result<void> start_over_with_schema();
    Result<void> ship_batch(const OutboxBatch& batch, const std::function<void()>& meanwhile);
    Result<void> make_partitions(const ForwardBatch& rows);
    template <typename Steps>
    Result<void> in_transaction(Steps steps);
    Result<void> ship(const HistorianBatch& batch, const std::function<void()>& meanwhile);
    Result<void> cleared(const OutboxBatch& batch);
    Result<void> forward_writes();
    Result<void> ship_writes();
    void refresh_waiting();
    std::int64_t now_ms() const;
    void log(const std::string& message) const;

    ForwardOptions options_;
    std::chrono::seconds keep_;
    Clock wall_clock_;
    std::function<void(const std::string&)> log_;
    std::mutex mutex_;  // one forward at a time: the connections and caches below
    Outbox outbox_;
    std::optional<postgres::Connection> remote_;
    // Local series id -> the historian's: learnt per connection, and again whenever a batch
    // fails (start_over_with_schema); each batch verifies the ones it uses (verify_series).
    std::map<std::int64_t, std::int64_t> remote_ids_;
    std::map<std::int64_t, SeriesNames> local_names_;  // local series id -> its names in the file
    std::set<std::int64_t> partitions_;                // days known to have a partition
    // The (t, id) of the last audit row the historian has of this gateway's file; none: to be
    // asked of it (a new connection, a failed batch).
    std::optional<std::pair<std::int64_t, std::int64_t>> writes_shipped_;
    std::string last_failed_state_;                    // the SQLSTATE of in_transaction's last failure
    bool connected_once_ = false;
    std::atomic<std::uint64_t> waiting_{0};
    std::atomic<std::uint64_t> forwarded_{0};
    std::atomic<std::int64_t> oldest_ms_{0};  // 0: none waiting
    std::atomic<std::uint64_t> errors_{0};
    std::jthread thread_;  // last: stops and joins first
};

// For `loopwire gateway --check`: connects once and checks or creates the schema; the error says
// what was wrong (a wrong password, a missing database, a newer schema) and what to do.
Result<void> check_forward_target(const ForwardOptions& options);

}  // namespace loopwire::gateway
