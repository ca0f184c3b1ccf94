#include "gateway/history_store.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "client/device_status.hpp"
#include "client/monitor_state.hpp"
#include "common/thread_name.hpp"
#include "gateway/history_schema.hpp"

namespace loopwire::gateway {
namespace {

using std::chrono::milliseconds;

constexpr std::int64_t minute_ms = 60000;
// Rows one retention statement deletes at most: a few milliseconds of work, so the writer's
// next commit never waits long behind a sweep of months of expired rows.
constexpr std::int64_t retention_batch = 5000;
// How often expired rows are looked for once a sweep found none left.
constexpr milliseconds retention_interval{60000};

std::int64_t to_ms(SystemTime time) { return std::chrono::duration_cast<milliseconds>(time.time_since_epoch()).count(); }
std::int64_t floor_div(std::int64_t a, std::int64_t b) { return a / b - ((a % b != 0) && ((a < 0) != (b < 0)) ? 1 : 0); }

// The number a value is kept as: the number itself, or the raw word of an enum label or a bit
// field (their text is kept beside it). None in a special state.
std::optional<double> number_of(const device::EngineeringValue& value) {
    if (const auto* number = std::get_if<double>(&value.value)) return *number;
    if (std::holds_alternative<std::monostate>(value.value)) return std::nullopt;
    return static_cast<double>(value.raw);
}

}  // namespace

struct HistoryStore::Writer {
    sqlite::Connection db;
    sqlite::Statement find_series;
    sqlite::Statement add_series;
    sqlite::Statement add_sample;
    sqlite::Statement add_minute;
    sqlite::Statement expire_samples;
    sqlite::Statement expire_minutes;
    sqlite::Statement add_outbox;  // prepared only with an outbox
    sqlite::Statement add_write;
    sqlite::Statement expire_writes;
    std::uint64_t outbox_added = 0;  // in the transaction being written, and the first's stamp
    std::int64_t outbox_first_t = 0;
    // Looked up with std::tie of the row's strings (std::less<>): no copies per row.
    std::map<std::tuple<std::string, std::string, std::string>, std::int64_t, std::less<>> series_ids;
    // Retention: the series still to sweep in this pass, and when the next pass is due.
    std::vector<std::int64_t> to_sweep;
    std::optional<SystemTime> next_sweep;
    std::uint64_t dropped_logged = 0;
    bool failing = false;  // the last commit failed (logged once until one succeeds)
};

HistoryStore::HistoryStore(HistoryOptions options) : options_(std::move(options)) {}

namespace {

struct Statements {
    const char* find_series = "SELECT id FROM series WHERE device = ?1 AND parameter = ?2 AND unit = ?3";
    const char* add_series = "INSERT INTO series(device, parameter, unit) VALUES(?1, ?2, ?3)";
    // A second row at the same millisecond (a heartbeat meeting a change) keeps the first.
    const char* add_sample = "INSERT OR IGNORE INTO samples(series_id, t, value, text, status) VALUES(?1, ?2, ?3, ?4, ?5)";
    const char* add_minute =
        "INSERT INTO minutes(series_id, minute, lo, hi, total, n) VALUES(?1, ?2, ?3, ?4, ?5, ?6) "
        "ON CONFLICT(series_id, minute) DO UPDATE SET lo = min(lo, excluded.lo), hi = max(hi, excluded.hi), "
        "total = total + excluded.total, n = n + excluded.n";
    // At most ?3 rows: those up to the ?3-th oldest, and older than the cutoff.
    const char* expire_samples =
        "DELETE FROM samples WHERE series_id = ?1 AND t < ?2 AND t <= "
        "coalesce((SELECT t FROM samples WHERE series_id = ?1 ORDER BY t LIMIT 1 OFFSET ?3 - 1), ?2)";
    const char* expire_minutes =
        "DELETE FROM minutes WHERE series_id = ?1 AND minute < ?2 AND minute <= "
        "coalesce((SELECT minute FROM minutes WHERE series_id = ?1 ORDER BY minute LIMIT 1 OFFSET ?3 - 1), ?2)";
    const char* add_outbox = "INSERT INTO outbox(series_id, t) VALUES(?1, ?2)";
    const char* add_write =
        "INSERT INTO writes(t, front, peer, user, device, parameter, old_value, new_value, outcome) "
        "VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)";
    const char* expire_writes = "DELETE FROM writes WHERE t < ?1";
};

}  // namespace

Result<std::unique_ptr<HistoryStore>> HistoryStore::open(HistoryOptions options, const std::vector<HistorySeriesName>& declared) {
    if (!options.wall_clock) options.wall_clock = [] { return std::chrono::system_clock::now(); };
    auto db = history::open_for_writing(options.database);
    if (!db) return db.error();
    std::unique_ptr<HistoryStore> store(new HistoryStore(std::move(options)));
    auto writer = std::make_unique<Writer>();
    writer->db = std::move(*db);
    const Statements sql;
    const std::pair<sqlite::Statement*, const char*> statements[] = {
        {&writer->find_series, sql.find_series}, {&writer->add_series, sql.add_series},
        {&writer->add_sample, sql.add_sample},   {&writer->add_minute, sql.add_minute},
        {&writer->expire_samples, sql.expire_samples}, {&writer->expire_minutes, sql.expire_minutes},
        {&writer->add_write, sql.add_write},           {&writer->expire_writes, sql.expire_writes}};
    for (const auto& [statement, text] : statements) {
        auto prepared = writer->db.prepare(text);
        if (!prepared) return prepared.error();
        *statement = std::move(*prepared);
    }
    if (store->options_.outbox) {
        auto prepared = writer->db.prepare(sql.add_outbox);
        if (!prepared) return prepared.error();
        writer->add_outbox = std::move(*prepared);
    }
    store->writer_ = std::move(writer);
    if (!declared.empty()) {
        if (auto begun = store->writer_->db.execute("BEGIN IMMEDIATE"); !begun) return begun.error();
        for (const auto& name : declared) {
            auto id = store->series_id(name.device, name.parameter, name.unit);
            if (!id) {
                (void)store->writer_->db.execute("ROLLBACK");
                return id.error();
            }
        }
        if (auto committed = store->writer_->db.execute("COMMIT"); !committed) return committed.error();
    }
    return store;
}

void HistoryStore::start() {
    if (thread_.joinable()) return;
    thread_ = std::jthread([this](std::stop_token stop) { run(std::move(stop)); });
    name_thread(thread_.native_handle(), "lw-history");
}

HistoryStore::~HistoryStore() {
    thread_ = std::jthread();  // stops and joins the writer
    if (writer_) {
        if (auto written = write_pending(); !written) log(written.error().message);
    }
    if (also_write_) also_write_();
}

SystemTime HistoryStore::wall_now() const { return options_.wall_clock(); }

void HistoryStore::log(const std::string& message) const {
    if (options_.log) options_.log("history: " + message);
}

void HistoryStore::record(const ValueChange& change) {
    if (change.about_device()) return;
    QueuedRow row;
    row.device = change.device;
    row.parameter = change.parameter;
    row.unit = change.unit;
    row.t = to_ms(change.sampled);
    if (change.value) {
        row.value = number_of(*change.value);
        if (!std::holds_alternative<double>(change.value->value) && row.value) row.text = change.text;
    }
    if (change.status != "ok") row.status = change.status;
    std::lock_guard lock(queue_mutex_);
    if (queue_.size() >= options_.max_queued) {
        ++dropped_;  // logged by the writer: this thread must not wait for a log
        return;
    }
    queue_.push_back(std::move(row));
}

void HistoryStore::record_write(const AuditRecord& record) {
    std::lock_guard lock(queue_mutex_);
    // Few (a person's or a program's writes), and each one matters: not bounded by max_queued.
    writes_queue_.push_back(record);
}

void HistoryStore::run_in_writer(WriterJob job) {
    std::lock_guard lock(queue_mutex_);
    jobs_.push_back(std::move(job));
}

std::uint64_t HistoryStore::rows_written() const {
    std::lock_guard lock(queue_mutex_);
    return rows_written_;
}

std::uint64_t HistoryStore::dropped() const {
    std::lock_guard lock(queue_mutex_);
    return dropped_;
}

// Commits every commit_interval, whatever else the gateway does: nothing but the stop wakes it
// early (the destructor then writes what is left).
void HistoryStore::run(std::stop_token stop) {
    using steady = std::chrono::steady_clock;
    auto next_commit = steady::now() + options_.commit_interval;
    while (!stop.stop_requested()) {
        {
            std::unique_lock lock(queue_mutex_);
            stop_woken_.wait_until(lock, stop, next_commit, [] { return false; });
        }
        if (stop.stop_requested()) break;
        (void)write_pending();  // failures are logged there and retried on the next round
        if (also_write_) also_write_();
        next_commit = steady::now() + options_.commit_interval;
    }
}

Result<std::int64_t> HistoryStore::series_id(const std::string& device, const std::string& parameter, const std::string& unit) {
    Writer& w = *writer_;
    if (auto known = w.series_ids.find(std::tie(device, parameter, unit)); known != w.series_ids.end()) return known->second;
    w.find_series.bind(1, std::string_view(device));
    w.find_series.bind(2, std::string_view(parameter));
    w.find_series.bind(3, std::string_view(unit));
    auto found = w.find_series.step();
    std::optional<std::int64_t> id;
    if (found && *found) id = w.find_series.integer(0);
    w.find_series.reset();
    if (!found) return found.error();
    if (!id) {
        w.add_series.bind(1, std::string_view(device));
        w.add_series.bind(2, std::string_view(parameter));
        w.add_series.bind(3, std::string_view(unit));
        auto added = w.add_series.step();
        w.add_series.reset();
        if (!added) return added.error();
        id = w.db.last_insert_id();
    }
    w.series_ids.emplace(std::make_tuple(device, parameter, unit), *id);
    return *id;
}

namespace {

struct MinuteAggregate {
    double lo = 0;
    double hi = 0;
    double total = 0;
    std::int64_t n = 0;
};

}  // namespace

Result<void> HistoryStore::insert_rows(const std::vector<QueuedRow>& rows, std::uint64_t& inserted) {
    Writer& w = *writer_;
    std::map<std::pair<std::int64_t, std::int64_t>, MinuteAggregate> minutes;
    for (const QueuedRow& row : rows) {
        auto id = series_id(row.device, row.parameter, row.unit);
        if (!id) return id.error();
        w.add_sample.bind(1, *id);
        w.add_sample.bind(2, row.t);
        w.add_sample.bind(3, row.value);
        w.add_sample.bind(4, row.text);
        w.add_sample.bind(5, row.status);
        auto added = w.add_sample.step();
        w.add_sample.reset();
        if (!added) return added.error();
        if (w.db.changes() != 1) continue;  // already there: counted once
        ++inserted;
        if (options_.outbox) {
            w.add_outbox.bind(1, *id);
            w.add_outbox.bind(2, row.t);
            auto noted = w.add_outbox.step();
            w.add_outbox.reset();
            if (!noted) return noted.error();
            if (w.outbox_added++ == 0) w.outbox_first_t = row.t;
        }
        if (!row.value) continue;
        MinuteAggregate& minute = minutes[{*id, floor_div(row.t, minute_ms)}];
        const double v = *row.value;
        if (minute.n == 0 || v < minute.lo) minute.lo = v;
        if (minute.n == 0 || v > minute.hi) minute.hi = v;
        minute.total += v;
        ++minute.n;
    }
    for (const auto& [key, minute] : minutes) {
        w.add_minute.bind(1, key.first);
        w.add_minute.bind(2, key.second);
        w.add_minute.bind(3, minute.lo);
        w.add_minute.bind(4, minute.hi);
        w.add_minute.bind(5, minute.total);
        w.add_minute.bind(6, minute.n);
        auto added = w.add_minute.step();
        w.add_minute.reset();
        if (!added) return added.error();
    }
    return {};
}

Result<std::uint64_t> HistoryStore::commit(const std::vector<QueuedRow>& rows) {
    Writer& w = *writer_;
    if (rows.empty()) return std::uint64_t{0};
    if (auto begun = w.db.execute("BEGIN IMMEDIATE"); !begun) return begun.error();
    std::uint64_t inserted = 0;
    w.outbox_added = 0;
    auto written = insert_rows(rows, inserted);
    if (written) written = w.db.execute("COMMIT");
    if (!written) {
        (void)w.db.execute("ROLLBACK");
        w.series_ids.clear();  // ids of series added in the rolled-back transaction are gone
        return written.error();
    }
    if (outbox_noted_ && w.outbox_added > 0) outbox_noted_(w.outbox_added, w.outbox_first_t);
    return inserted;
}

Result<void> HistoryStore::commit_writes(const std::vector<AuditRecord>& writes) {
    Writer& w = *writer_;
    if (writes.empty()) return {};
    if (auto begun = w.db.execute("BEGIN IMMEDIATE"); !begun) return begun.error();
    Result<void> written;
    for (const AuditRecord& record : writes) {
        w.add_write.bind(1, to_ms(record.time));
        const std::string* texts[] = {&record.origin.front, &record.origin.peer,  &record.origin.user, &record.device,
                                      &record.parameter,    &record.old_value,    &record.new_value,   &record.outcome};
        int column = 2;
        for (const std::string* text : texts) w.add_write.bind(column++, std::string_view(*text));
        auto added = w.add_write.step();
        w.add_write.reset();
        if (!added) {
            written = added.error();
            break;
        }
    }
    if (written) written = w.db.execute("COMMIT");
    if (!written) (void)w.db.execute("ROLLBACK");
    return written;
}

Result<void> HistoryStore::run_jobs(std::vector<WriterJob>& jobs) {
    Writer& w = *writer_;
    std::size_t done = 0;
    Result<void> outcome;
    for (; done < jobs.size(); ++done) {
        if (outcome = w.db.execute("BEGIN IMMEDIATE"); !outcome) break;
        outcome = jobs[done](w.db);
        if (outcome) outcome = w.db.execute("COMMIT");
        if (!outcome) {
            (void)w.db.execute("ROLLBACK");
            break;
        }
    }
    jobs.erase(jobs.begin(), jobs.begin() + static_cast<std::ptrdiff_t>(done));
    return outcome;
}

// A row that says nothing was read is never repeated by a heartbeat: a heartbeat of it would
// stamp the present on a reading nobody made, which is how a frozen value used to look fresh
// for minutes.
bool holds_reading(const std::optional<std::string>& status) {
    if (!status) return true;  // "ok"
    using device::DeviceStatus;
    const auto is = [&](DeviceStatus device_status) { return *status == device::status_text(device_status); };
    return !is(DeviceStatus::stale) && !is(DeviceStatus::no_reply) && !is(DeviceStatus::line_down) &&
           !is(DeviceStatus::wrong_device) && *status != device::failed_value_status && !is(DeviceStatus::waiting);
}

// Every value whose last row is `heartbeat` old or older is written again at the current time,
// so a value that holds still draws a flat line, not a gap. Only a value still current: once it
// is stale (gateway/value_cache.hpp) its row says so and the line stops there.
void HistoryStore::add_heartbeats(std::vector<QueuedRow>& batch) {
    for (const QueuedRow& row : batch) {
        auto& last = last_[{row.device, row.parameter}];
        // A change stamped before a heartbeat already written (its sample started before the
        // heartbeat, or it went stale just then) is still newer than the reading the
        // heartbeat repeated: it replaces it, or the old reading would be repeated for ever.
        if (row.t >= last.t || last.heartbeat) last = row;
    }
    const std::int64_t now = to_ms(wall_now());
    const std::int64_t interval = options_.heartbeat.count();
    for (auto& [key, last] : last_) {
        if (now - last.t < interval || !holds_reading(last.status)) continue;
        last.t = now;
        last.heartbeat = true;
        batch.push_back(last);
    }
}

Result<std::int64_t> HistoryStore::expire(sqlite::Statement& statement, std::int64_t series, std::int64_t before) {
    statement.bind(1, series);
    statement.bind(2, before);
    statement.bind(3, retention_batch);
    auto done = statement.step();
    statement.reset();
    if (!done) return done.error();
    return static_cast<std::int64_t>(writer_->db.changes());
}

Result<bool> HistoryStore::retention_step(bool force) {
    Writer& w = *writer_;
    const SystemTime now = wall_now();
    if (w.to_sweep.empty()) {
        if (!force && w.next_sweep && now < *w.next_sweep) return false;
        w.next_sweep = now + retention_interval;
        // The audit's rows go with the samples of their age; few, so in one statement.
        w.expire_writes.bind(1, to_ms(now) - std::chrono::duration_cast<milliseconds>(options_.keep).count());
        auto expired = w.expire_writes.step();
        w.expire_writes.reset();
        if (!expired) return expired.error();
        auto ids = w.db.prepare("SELECT id FROM series ORDER BY id DESC");
        if (!ids) return ids.error();
        for (;;) {
            auto row = ids->step();
            if (!row) return row.error();
            if (!*row) break;
            w.to_sweep.push_back(ids->integer(0));
        }
        if (w.to_sweep.empty()) return false;
    }
    const std::int64_t cutoff = to_ms(now) - std::chrono::duration_cast<milliseconds>(options_.keep).count();
    const std::int64_t series = w.to_sweep.back();
    auto samples = expire(w.expire_samples, series, cutoff);
    if (!samples) return samples.error();
    // A minute goes once all of it is older than the cutoff.
    auto minutes = expire(w.expire_minutes, series, floor_div(cutoff, minute_ms));
    if (!minutes) return minutes.error();
    if (*samples < retention_batch && *minutes < retention_batch) w.to_sweep.pop_back();  // this series is done
    return true;
}

Result<void> HistoryStore::write_pending() {
    Writer& w = *writer_;
    std::vector<QueuedRow> batch;
    std::vector<AuditRecord> writes;
    std::vector<WriterJob> jobs;
    std::uint64_t dropped = 0;
    {
        std::lock_guard lock(queue_mutex_);
        batch.swap(queue_);
        writes.swap(writes_queue_);
        jobs.swap(jobs_);
        dropped = dropped_;
    }
    if (auto audited = commit_writes(writes); !audited) {
        log(fmt::format("the audit of {} write(s) not written yet: {} (kept in memory and retried)", writes.size(),
                        audited.error().message));
        std::lock_guard lock(queue_mutex_);
        writes_queue_.insert(writes_queue_.begin(), std::make_move_iterator(writes.begin()), std::make_move_iterator(writes.end()));
    }
    if (dropped > w.dropped_logged) {
        log(fmt::format("{} change(s) not recorded: the database fell behind by {} queued rows (a slow or full disk?)",
                        dropped - w.dropped_logged, options_.max_queued));
        w.dropped_logged = dropped;
    }
    add_heartbeats(batch);
    auto committed = commit(batch);
    if (!committed) {
        if (!w.failing) log(fmt::format("{} (kept in memory and retried)", committed.error().message));
        w.failing = true;
        std::lock_guard lock(queue_mutex_);
        // Back in front of what came meanwhile, in order; what does not fit is dropped, counted.
        const std::size_t room = options_.max_queued > queue_.size() ? options_.max_queued - queue_.size() : 0;
        if (batch.size() > room) {
            dropped_ += batch.size() - room;
            batch.erase(batch.begin(), batch.begin() + static_cast<std::ptrdiff_t>(batch.size() - room));
        }
        queue_.insert(queue_.begin(), std::make_move_iterator(batch.begin()), std::make_move_iterator(batch.end()));
        jobs_.insert(jobs_.begin(), std::make_move_iterator(jobs.begin()), std::make_move_iterator(jobs.end()));
        return committed.error();
    }
    if (w.failing) log("writing again");
    w.failing = false;
    if (auto ran = run_jobs(jobs); !ran) {
        log(fmt::format("{} (kept in memory and retried)", ran.error().message));
        std::lock_guard lock(queue_mutex_);
        jobs_.insert(jobs_.begin(), std::make_move_iterator(jobs.begin()), std::make_move_iterator(jobs.end()));
    }
    {
        std::lock_guard lock(queue_mutex_);
        rows_written_ += *committed;
    }
    if (auto swept = retention_step(false); !swept) {
        log(swept.error().message);
        return swept.error();
    }
    return {};
}

Result<void> HistoryStore::enforce_retention() {
    writer_->to_sweep.clear();
    auto more = retention_step(true);
    while (more && *more && !writer_->to_sweep.empty()) more = retention_step(true);
    if (!more) return more.error();
    return {};
}

}  // namespace loopwire::gateway
