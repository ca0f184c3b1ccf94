#include "gateway/history_forwarder.hpp"

#include <algorithm>
#include <iterator>
#include <vector>

#include <fmt/format.h>

#include "common/thread_name.hpp"
#include "gateway/forward_batch.hpp"
#include "gateway/forwarding_unit.hpp"  // the GatewayLog level prefixes
#include "gateway/postgres_history_schema.hpp"

namespace loopwire::gateway {
namespace {

using std::chrono::milliseconds;

// A batch of rows all new to the historian (the usual case) goes in by COPY straight into the
// samples, as fast as PostgreSQL takes rows, and its minutes, computed here, by one upsert.
// A COPY that meets a (series, t) already there fails whole (a unique violation); that batch
// was sent before (a crash after PostgreSQL committed, before the outbox was cleared), and goes
// again the merging way: by COPY into a temporary table of the session, then one statement that
// moves only the new rows into the samples and upserts the minutes of those, so nothing counts
// twice. Either way in one transaction; the staging table empties itself at its end.
constexpr const char* copy_samples = "COPY loopwire_samples(series_id, t, value, text, status) FROM STDIN (FORMAT binary)";
constexpr const char* unique_violation = "23505";
constexpr const char* create_staging =
    "CREATE TEMPORARY TABLE IF NOT EXISTS loopwire_staging(series_id bigint, t bigint, value double precision, text text, status text) "
    "ON COMMIT DELETE ROWS";
constexpr const char* copy_staging = "COPY loopwire_staging FROM STDIN (FORMAT binary)";
// Both ways end by adding minutes to those of earlier batches.
constexpr const char* merge_minutes =
    " ON CONFLICT (series_id, minute) DO UPDATE SET"
    " lo = least(loopwire_minutes.lo, excluded.lo), hi = greatest(loopwire_minutes.hi, excluded.hi),"
    " total = loopwire_minutes.total + excluded.total, n = loopwire_minutes.n + excluded.n";
constexpr const char* upsert_minutes =
    "INSERT INTO loopwire_minutes(series_id, minute, lo, hi, total, n) "
    "SELECT * FROM unnest($1::bigint[], $2::bigint[], $3::float8[], $4::float8[], $5::float8[], $6::bigint[])";
constexpr const char* merge_staged =
    "WITH inserted AS ("
    " INSERT INTO loopwire_samples(series_id, t, value, text, status)"
    " SELECT series_id, t, value, text, status FROM loopwire_staging ON CONFLICT DO NOTHING"
    " RETURNING series_id, t, value) "
    "INSERT INTO loopwire_minutes(series_id, minute, lo, hi, total, n) "
    "SELECT series_id, floor(t / 60000.0)::bigint, min(value), max(value), sum(value), count(*) "
    "FROM inserted WHERE value IS NOT NULL GROUP BY 1, 2";

// The historian's ids of a batch's new series, added where missing, in one round trip: the
// rows `added` inserts are not visible to the second SELECT (one snapshot), so each series
// comes back once, from one side or the other.
constexpr const char* find_or_add_series = R"sql(
WITH wanted AS (SELECT * FROM unnest($2::text[], $3::text[], $4::text[]) AS w(device, parameter, unit)),
added AS (
  INSERT INTO loopwire_series(gateway, device, parameter, unit) SELECT $1, device, parameter, unit FROM wanted
  ON CONFLICT DO NOTHING RETURNING id, device, parameter, unit)
SELECT id, device, parameter, unit FROM added
UNION ALL SELECT s.id, s.device, s.parameter, s.unit FROM loopwire_series s JOIN wanted w USING (device, parameter, unit)
WHERE s.gateway = $1
)sql";

// The historian's series rows of a batch, as this forwarder knows them (id, device, parameter,
// unit), that are still there under its own gateway: locked (KEY SHARE) until the batch's
// transaction ends, so none can be deleted, nor its table dropped, before the batch is in. A
// batch goes in only when every one of its series is found: ids learnt earlier may have come to
// name another gateway's series (the tables dropped and made again, by hand or by another
// gateway's first connect), and a row filed under one of those would be that gateway's.
constexpr const char* verify_series = R"sql(
SELECT s.id FROM loopwire_series s
JOIN unnest($2::bigint[], $3::text[], $4::text[], $5::text[]) AS w(id, device, parameter, unit)
  ON s.id = w.id AND s.device = w.device AND s.parameter = w.parameter AND s.unit = w.unit
WHERE s.gateway = $1 FOR KEY SHARE OF s
)sql";

// The audit's rows: the last one the historian has of this gateway, and a batch of new ones
// (ON CONFLICT: one sent before is not doubled).
constexpr const char* last_write_shipped =
    "SELECT t, local_id FROM loopwire_writes WHERE gateway = $1 ORDER BY t DESC, local_id DESC LIMIT 1";
constexpr const char* insert_writes = R"sql(
INSERT INTO loopwire_writes(gateway, local_id, t, time, front, peer, user_name, device, parameter, old_value, new_value, outcome)
SELECT $1, w.local_id, w.t, to_timestamp(w.t / 1000.0), w.front, w.peer, w.user_name, w.device, w.parameter, w.old_value,
       w.new_value, w.outcome
FROM unnest($2::bigint[], $3::bigint[], $4::text[], $5::text[], $6::text[], $7::text[], $8::text[], $9::text[],
            $10::text[], $11::text[])
  AS w(local_id, t, front, peer, user_name, device, parameter, old_value, new_value, outcome)
ON CONFLICT DO NOTHING
)sql";
constexpr std::size_t writes_batch = 1000;

// How often the historian's expired partitions are looked for.
constexpr milliseconds partition_sweep_interval{std::chrono::hours(1)};

}  // namespace

HistoryForwarder::HistoryForwarder(ForwardOptions options, std::chrono::seconds keep, Clock wall_clock,
                                   std::function<void(const std::string&)> log)
    : options_(std::move(options)), keep_(keep), wall_clock_(std::move(wall_clock)), log_(std::move(log)) {}

Result<std::unique_ptr<HistoryForwarder>> HistoryForwarder::start(const std::filesystem::path& database,
                                                                  ForwardOptions options, std::chrono::seconds keep,
                                                                  Clock wall_clock,
                                                                  std::function<void(const std::string&)> log) {
    if (!wall_clock) wall_clock = [] { return std::chrono::system_clock::now(); };
    std::unique_ptr<HistoryForwarder> forwarder(
        new HistoryForwarder(std::move(options), keep, std::move(wall_clock), std::move(log)));
    auto outbox = Outbox::open(database);
    if (!outbox) return outbox.error();
    forwarder->outbox_ = std::move(*outbox);
    forwarder->refresh_waiting();
    if (forwarder->options_.thread) {
        forwarder->thread_ = std::jthread([f = forwarder.get()](std::stop_token stop) { f->run(std::move(stop)); });
        name_thread(forwarder->thread_.native_handle(), "lw-forwarder");
    }
    return forwarder;
}

HistoryForwarder::~HistoryForwarder() { thread_ = std::jthread(); }

std::int64_t HistoryForwarder::now_ms() const {
    return std::chrono::duration_cast<milliseconds>(wall_clock_().time_since_epoch()).count();
}

void HistoryForwarder::log(const std::string& message) const {
    if (log_) log_("history: " + message);
}

ForwardStats HistoryForwarder::stats() const {
    ForwardStats stats;
    stats.waiting_rows = waiting_.load();
    stats.forwarded_total = forwarded_.load();
    stats.errors_total = errors_.load();
    if (const std::int64_t oldest = oldest_ms_.load(); oldest != 0 && stats.waiting_rows != 0) {
        stats.oldest_waiting_seconds = std::max(0.0, static_cast<double>(now_ms() - oldest) / 1000.0);
    }
    return stats;
}

void HistoryForwarder::queued(std::uint64_t rows, std::int64_t first_t) {
    if (rows == 0) return;
    waiting_ += rows;
    std::int64_t none = 0;
    oldest_ms_.compare_exchange_strong(none, first_t);  // only when nothing was waiting
}

// The outbox's size and its oldest row, for /metrics: looked at after each round, not per scrape
// (a scrape must not wait for the forwarder's lock).
void HistoryForwarder::refresh_waiting() {
    auto count = outbox_.waiting();
    auto oldest = outbox_.oldest_t();
    if (count) waiting_ = static_cast<std::uint64_t>(*count);
    if (oldest) oldest_ms_ = *oldest;
}

Result<void> HistoryForwarder::connect() {
    if (remote_ && !remote_->broken()) return {};
    remote_.reset();
    remote_ids_.clear();
    partitions_.clear();
    writes_shipped_.reset();
    // A historian that stops answering (statement_timeout is the server's, which a frozen server
    // does not keep) is said so in the log, as is its return: the forwarder waits on meanwhile.
    postgres::StallWatch watch{[this](const std::string& line) {
        if (!log_) return;
        // A warning or notice still, its prefix kept first (GatewayLog).
        for (const std::string_view level : {gateway_warning_prefix, gateway_notice_prefix}) {
            if (line.starts_with(level)) return log_(fmt::format("{}history: {}", level, line.substr(level.size())));
        }
        log(line);
    }};
    auto db = postgres::Connection::connect(options_.conninfo, options_.password, options_.connect_timeout_seconds,
                                            "loopwire", std::move(watch));
    if (!db) return db.error();
    // A statement stuck behind a lock (another session's DDL on the samples) fails and is
    // retried rather than holding the forwarder for ever; a batch takes well under a second.
    if (auto bounded = db->run("SET statement_timeout = '120s'"); !bounded) return bounded.error();
    if (auto migrated = postgres_history::migrate(*db); !migrated) return migrated.error();
    if (auto staging = db->run(create_staging); !staging) return staging.error();
    // Once per forwarder, so the log says where the history goes; an outage's end is the
    // thread's to log, not every reconnect's.
    if (!connected_once_) log(fmt::format("forwarding to {}", db->server()));
    connected_once_ = true;
    remote_ = std::move(*db);
    return {};
}

// The batch's rows as the historian takes them: its series ids, COPY's data, the minutes, and
// the series rows to verify in the batch's transaction.
Result<HistoryForwarder::HistorianBatch> HistoryForwarder::for_historian(const OutboxBatch& batch) {
    if (auto learned = learn_series(batch); !learned) return learned.error();
    HistorianBatch out;
    std::set<std::int64_t> seen;
    std::vector<std::optional<std::string>> ids, devices, parameters, units;
    for (const OutboxRow& row : batch.rows) {
        const std::int64_t remote = remote_ids_.at(row.series);
        out.rows.add(remote, row.t, row.value, row.text, row.status);
        if (!seen.insert(row.series).second) continue;
        const SeriesNames& names = local_names_.at(row.series);
        ids.emplace_back(std::to_string(remote));
        devices.emplace_back(names.device);
        parameters.emplace_back(names.parameter);
        units.emplace_back(names.unit);
    }
    out.series = seen.size();
    out.series_check = {options_.gateway, postgres::array_literal(ids), postgres::array_literal(devices),
                        postgres::array_literal(parameters), postgres::array_literal(units)};
    return out;
}

// The local file's names of a series: they never change for an id the outbox holds, so they
// are read once per forwarder.
Result<const SeriesNames*> HistoryForwarder::local_names(std::int64_t series) {
    if (auto known = local_names_.find(series); known != local_names_.end()) return &known->second;
    auto names = outbox_.names(series);
    if (!names) return names.error();
    return &local_names_.emplace(series, std::move(*names)).first->second;
}

// In the batch's transaction, before its rows: every series the rows are filed under is still
// this gateway's, as this forwarder knows it (verify_series).
Result<void> HistoryForwarder::verified(const HistorianBatch& batch) {
    auto found = remote_->execute(verify_series, batch.series_check);
    if (!found) return found.error();
    if (static_cast<std::size_t>(found->rows()) == batch.series) return {};
    return make_error(ErrorKind::mismatch,
                      fmt::format("{}: {} of the batch's {} series ids no longer name this gateway's series in the historian "
                                  "(its tables were dropped or made again)",
                                  remote_->server(), batch.series - static_cast<std::size_t>(found->rows()), batch.series));
}

// After a batch failed on a connection that still works: what this forwarder knew of the
// historian may be what failed it (tables dropped, made again, a partition gone), so the series
// ids and partitions are learnt again, and missing tables made again.
Result<void> HistoryForwarder::start_over_with_schema() {
    remote_ids_.clear();
    partitions_.clear();
    writes_shipped_.reset();
    if (auto migrated = postgres_history::migrate(*remote_); !migrated) return migrated.error();
    return remote_->run(create_staging);
}

// One batch, shipped; a failure on a working connection is tried once more after
// start_over_with_schema(), so a historian whose tables were dropped and made again under this
// gateway takes the batch at once, under the right series, rather than after a reconnect.
Result<void> HistoryForwarder::ship_batch(const OutboxBatch& batch, const std::function<void()>& meanwhile) {
    Result<void> shipped;
    for (int attempt = 0; attempt < 2; ++attempt) {
        if (attempt == 1) {
            if (!remote_ || remote_->broken()) return shipped;
            const Error first = shipped.error();
            if (auto again = start_over_with_schema(); !again) return first;
            log(fmt::format("the historian's tables or series changed under this gateway ({}); made again where missing, "
                            "series ids learnt again",
                            first.message));
        }
        auto rows = for_historian(batch);
        shipped = rows ? ship(*rows, meanwhile) : Result<void>(rows.error());
        if (shipped) return shipped;
    }
    return shipped;
}

// The historian's ids of the batch's series not met yet on this connection (all of them on its
// first batch), looked up or added together.
Result<void> HistoryForwarder::learn_series(const OutboxBatch& batch) {
    using Names = std::tuple<std::string, std::string, std::string>;
    std::map<Names, std::int64_t> unknown;  // -> the local id
    std::set<std::int64_t> seen;
    std::vector<std::optional<std::string>> devices, parameters, units;
    for (const OutboxRow& row : batch.rows) {
        if (remote_ids_.count(row.series) != 0 || !seen.insert(row.series).second) continue;
        auto names = local_names(row.series);
        if (!names) return names.error();
        const SeriesNames& known = **names;
        unknown.emplace(Names{known.device, known.parameter, known.unit}, row.series);
        devices.emplace_back(known.device);
        parameters.emplace_back(known.parameter);
        units.emplace_back(known.unit);
    }
    if (unknown.empty()) return {};
    auto found = remote_->execute(find_or_add_series, {options_.gateway, postgres::array_literal(devices),
                                                       postgres::array_literal(parameters), postgres::array_literal(units)});
    if (!found) return found.error();
    for (int i = 0; i < found->rows(); ++i) {
        const auto local = unknown.find(Names{found->text(i, 1), found->text(i, 2), found->text(i, 3)});
        if (local != unknown.end()) remote_ids_.emplace(local->second, found->integer(i, 0));
    }
    if (std::any_of(unknown.begin(), unknown.end(), [&](const auto& entry) { return remote_ids_.count(entry.second) == 0; })) {
        return make_error(ErrorKind::mismatch, fmt::format("{}: no id for a series", remote_->server()));
    }
    return {};
}

// The partitions of the days the batch has rows in, and of tomorrow, so that a day's first rows
// do not wait for theirs; only those: rows from an old outage make none for the days between.
Result<void> HistoryForwarder::make_partitions(const ForwardBatch& rows) {
    std::set<std::int64_t> days = rows.days();
    days.insert(postgres_history::day_of(now_ms() + postgres_history::day_ms));
    std::vector<std::int64_t> missing;
    std::set_difference(days.begin(), days.end(), partitions_.begin(), partitions_.end(), std::back_inserter(missing));
    if (missing.empty()) return {};
    if (auto made = postgres_history::ensure_partitions(*remote_, missing); !made) return made.error();
    partitions_.insert(missing.begin(), missing.end());
    return {};
}

// Runs `steps` in one transaction of the historian; rolls back on failure.
template <typename Steps>
Result<void> HistoryForwarder::in_transaction(Steps steps) {
    if (auto begun = remote_->run("BEGIN"); !begun) return begun.error();
    Result<void> done = steps();
    if (done) done = remote_->run("COMMIT");
    if (!done && !remote_->broken()) {
        const std::string state = remote_->failed_state();  // the failure's, not the rollback's
        (void)remote_->execute("ROLLBACK");
        last_failed_state_ = state;
    }
    return done;
}

// `meanwhile` runs once the rows are sent, while the server takes them (unless sending failed).
Result<void> HistoryForwarder::ship(const HistorianBatch& batch, const std::function<void()>& meanwhile) {
    const ForwardBatch& rows = batch.rows;
    if (rows.rows() == 0) return {};
    if (auto made = make_partitions(rows); !made) return made.error();
    last_failed_state_.clear();
    const std::string data = rows.copy_data();
    auto copied = in_transaction([&]() -> Result<void> {
        if (auto checked = verified(batch); !checked) return checked.error();
        if (auto sent = remote_->copy_send(copy_samples, data); !sent) return sent.error();
        meanwhile();
        if (auto taken = remote_->copy_finish(); !taken) return taken.error();
        if (rows.minutes().empty()) return {};
        return remote_->run(std::string(upsert_minutes) + merge_minutes, rows.minute_columns());
    });
    if (copied || last_failed_state_ != unique_violation) return copied;
    return in_transaction([&]() -> Result<void> {
        if (auto checked = verified(batch); !checked) return checked.error();
        if (auto sent = remote_->copy_in(copy_staging, data); !sent) return sent.error();
        return remote_->run(std::string(merge_staged) + merge_minutes);
    });
}

// Only once PostgreSQL committed the batch: a crash before this sends the batch again.
Result<void> HistoryForwarder::cleared(const OutboxBatch& batch) {
    if (auto cleared = outbox_.clear(batch.last_seq); !cleared) return cleared.error();
    forwarded_ += batch.rows.size();
    if (batch.expired != 0) {
        log(fmt::format("{} row(s) were deleted locally after `keep` before they could be forwarded", batch.expired));
    }
    return {};
}

// Ships the outbox batch after batch until it is empty. While the server takes a batch's COPY,
// the file's side works at once: it clears the batch committed before (a crash before that sends
// it again, which the merging way absorbs) and reads the next one.
Result<void> HistoryForwarder::forward_all() {
    auto batch = outbox_.read(0, options_.batch_rows);
    std::optional<OutboxBatch> committed;  // in the historian, not yet cleared from the outbox
    Result<void> done;
    while (done && batch && !batch->empty()) {
        const std::int64_t last = batch->last_seq;
        std::optional<Result<OutboxBatch>> next;
        // May run twice (a batch tried again): the second time it only reads the next again.
        const auto meanwhile = [&] {
            if (committed) done = cleared(*committed);
            committed.reset();
            next = outbox_.read(last, options_.batch_rows);
        };
        if (auto shipped = ship_batch(*batch, meanwhile); !shipped) {
            done = shipped.error();
            break;
        }
        if (!next) meanwhile();
        committed = std::move(*batch);
        batch = std::move(*next);
    }
    if (committed) {
        auto clear = cleared(*committed);
        if (done) done = clear;
    }
    if (done && !batch) return batch.error();
    return done;
}

// The audit rows the historian does not have yet; a failure on a working connection is tried
// once more after start_over_with_schema(), as a batch of samples is (its table dropped under
// this gateway: made again, and every row of the file sent to it).
Result<void> HistoryForwarder::forward_writes() {
    auto shipped = ship_writes();
    if (shipped || !remote_ || remote_->broken()) return shipped;
    if (auto again = start_over_with_schema(); !again) return shipped;
    return ship_writes();
}

// A batch a statement (each its own transaction); a failure makes the next try ask the
// historian where it is again.
Result<void> HistoryForwarder::ship_writes() {
    if (!writes_shipped_) {
        auto last = remote_->execute(last_write_shipped, {options_.gateway});
        if (!last) return last.error();
        writes_shipped_.emplace(0, 0);
        if (last->rows() == 1) writes_shipped_.emplace(last->integer(0, 0), last->integer(0, 1));
    }
    for (;;) {
        auto rows = outbox_.writes_after(writes_shipped_->first, writes_shipped_->second, writes_batch);
        if (!rows) return rows.error();
        if (rows->empty()) return {};
        std::vector<std::vector<std::optional<std::string>>> columns(10);
        for (const LocalWrite& row : *rows) {
            columns[0].emplace_back(std::to_string(row.id));
            columns[1].emplace_back(std::to_string(row.t));
            for (std::size_t i = 0; i < row.fields.size() && i + 2 < columns.size(); ++i) {
                columns[i + 2].emplace_back(row.fields[i]);
            }
        }
        postgres::Parameters parameters{options_.gateway};
        for (const auto& column : columns) parameters.emplace_back(postgres::array_literal(column));
        if (auto shipped = remote_->run(insert_writes, parameters); !shipped) {
            writes_shipped_.reset();
            return shipped.error();
        }
        writes_shipped_.emplace(rows->back().t, rows->back().id);
        if (rows->size() < writes_batch) return {};
    }
}

Result<std::uint64_t> HistoryForwarder::forward_pending() {
    std::lock_guard lock(mutex_);
    const std::uint64_t before = forwarded_.load();
    Result<void> done = connect();
    if (done) done = forward_all();
    if (done) done = forward_writes();
    refresh_waiting();
    if (!done) {
        ++errors_;
        if (remote_ && remote_->broken()) remote_.reset();
        return done.error();
    }
    return forwarded_.load() - before;
}

Result<void> HistoryForwarder::drop_expired_partitions() {
    std::lock_guard lock(mutex_);
    if (auto connected = connect(); !connected) return connected.error();
    const std::int64_t cutoff = now_ms() - std::chrono::duration_cast<milliseconds>(keep_).count();
    auto dropped = postgres_history::drop_partitions_before(*remote_, cutoff);
    if (!dropped) return dropped.error();
    partitions_.clear();
    if (*dropped != 0) log(fmt::format("dropped {} day partition(s) of the historian older than `keep`", *dropped));
    return {};
}

void HistoryForwarder::run(std::stop_token stop) {
    std::mutex wait_mutex;
    std::condition_variable_any woken;
    std::unique_lock wait_lock(wait_mutex);
    auto pause = [&](milliseconds how_long) { woken.wait_for(wait_lock, stop, how_long, [] { return false; }); };
    milliseconds retry = options_.retry_first;
    bool outage = false;
    std::optional<std::chrono::steady_clock::time_point> next_sweep;
    while (!stop.stop_requested()) {
        auto shipped = forward_pending();
        if (!shipped) {
            if (!outage) {
                log(fmt::format("forwarding paused: {}; rows wait in the local file and are retried", shipped.error().message));
            }
            outage = true;
            pause(retry);
            retry = std::min(retry * 2, options_.retry_max);
            continue;
        }
        if (outage) log(fmt::format("forwarding again ({} rows wait)", waiting_.load()));
        outage = false;
        retry = options_.retry_first;
        const auto now = std::chrono::steady_clock::now();
        if (!next_sweep || now >= *next_sweep) {
            next_sweep = now + partition_sweep_interval;
            if (auto swept = drop_expired_partitions(); !swept) log(swept.error().message);
        }
        pause(options_.idle_poll);
    }
}

Result<void> check_forward_target(const ForwardOptions& options) {
    auto db = postgres::Connection::connect(options.conninfo, options.password, options.connect_timeout_seconds);
    if (!db) return db.error();
    return postgres_history::migrate(*db);
}

}  // namespace loopwire::gateway
