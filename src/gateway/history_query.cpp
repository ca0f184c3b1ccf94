#include "gateway/history_query.hpp"

#include <algorithm>
#include <map>

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace loopwire::gateway {

namespace {

constexpr std::int64_t minute_ms = 60000;

std::int64_t floor_div(std::int64_t a, std::int64_t b) { return a / b - ((a % b != 0) && ((a < 0) != (b < 0)) ? 1 : 0); }
std::int64_t ceil_div(std::int64_t a, std::int64_t b) { return -floor_div(-a, b); }

}  // namespace

// Buckets narrower than a minute are computed from the samples. Wider ones are rounded up to
// whole minutes and start on a minute, so that every minute lies in one bucket and the minute
// table answers for all of those inside [from, to]; the minutes cut by `from` or `to` are read
// from the samples. Rounding up keeps the count at most `points`.
BucketPlan plan_buckets(std::int64_t from, std::int64_t to, std::size_t points) {
    const auto count = static_cast<std::int64_t>(points == 0 ? 1 : points);
    const std::int64_t span = to - from + 1;
    BucketPlan plan;
    plan.origin = from;
    plan.width = std::max<std::int64_t>(1, ceil_div(span, count));
    if (plan.width < minute_ms) return plan;
    plan.minutes = true;
    plan.origin = floor_div(from, minute_ms) * minute_ms;
    plan.width = ceil_div(plan.width, minute_ms) * minute_ms;
    while (ceil_div(to + 1 - plan.origin, plan.width) > count) plan.width += minute_ms;
    return plan;
}

MinuteSpan whole_minutes(std::int64_t from, std::int64_t to) {
    return {ceil_div(from, minute_ms), floor_div(to + 1, minute_ms)};
}

namespace history {
namespace {

using std::chrono::milliseconds;

std::int64_t to_ms(std::chrono::system_clock::time_point time) {
    return std::chrono::duration_cast<milliseconds>(time.time_since_epoch()).count();
}

struct Aggregate {
    double min = 0;
    double max = 0;
    double sum = 0;
    std::int64_t count = 0;

    void add(double lo, double hi, double total, std::int64_t n) {
        if (n <= 0) return;
        if (count == 0 || lo < min) min = lo;
        if (count == 0 || hi > max) max = hi;
        sum += total;
        count += n;
    }
};

using Buckets = std::map<std::int64_t, Aggregate>;

// The rows come in key order (time), so each is added to its bucket as it is read: no sort,
// which a GROUP BY on the bucket number would need (and which cost more than the reading).
std::int64_t bucket_of(const BucketPlan& plan, std::int64_t t) { return (t - plan.origin) / plan.width; }

Result<void> gather_samples(sqlite::Connection& db, std::int64_t series, const BucketPlan& plan, std::int64_t from,
                            std::int64_t to, Buckets& buckets) {
    if (from > to) return {};
    // Special states and missed replies are rows without a value: no part of a bucket.
    auto statement = db.prepare(
        "SELECT t, value FROM samples WHERE series_id = ?1 AND t >= ?2 AND t <= ?3 AND value IS NOT NULL ORDER BY t");
    if (!statement) return statement.error();
    statement->bind(1, series);
    statement->bind(2, from);
    statement->bind(3, to);
    for (;;) {
        auto row = statement->step();
        if (!row) return row.error();
        if (!*row) return {};
        const double value = statement->real(1);
        buckets[bucket_of(plan, statement->integer(0))].add(value, value, value, 1);
    }
}

Result<void> gather_minutes(sqlite::Connection& db, std::int64_t series, const BucketPlan& plan, std::int64_t first,
                            std::int64_t end, Buckets& buckets) {
    auto statement = db.prepare(
        "SELECT minute, lo, hi, total, n FROM minutes WHERE series_id = ?1 AND minute >= ?2 AND minute < ?3 ORDER BY minute");
    if (!statement) return statement.error();
    statement->bind(1, series);
    statement->bind(2, first);
    statement->bind(3, end);
    for (;;) {
        auto row = statement->step();
        if (!row) return row.error();
        if (!*row) return {};
        buckets[bucket_of(plan, statement->integer(0) * minute_ms)].add(statement->real(1), statement->real(2),
                                                                        statement->real(3), statement->integer(4));
    }
}

Result<std::vector<HistoryBucket>> buckets_of(sqlite::Connection& db, std::int64_t series, std::int64_t from, std::int64_t to,
                                              std::size_t points) {
    const BucketPlan plan = plan_buckets(from, to, points);
    Buckets buckets;
    if (!plan.minutes) {
        if (auto done = gather_samples(db, series, plan, from, to, buckets); !done) return done.error();
    } else {
        const auto [first, end] = whole_minutes(from, to);
        if (first < end) {
            if (auto done = gather_samples(db, series, plan, from, first * minute_ms - 1, buckets); !done) return done.error();
            if (auto done = gather_minutes(db, series, plan, first, end, buckets); !done) return done.error();
            if (auto done = gather_samples(db, series, plan, end * minute_ms, to, buckets); !done) return done.error();
        } else if (auto done = gather_samples(db, series, plan, from, to, buckets); !done) {
            return done.error();
        }
    }
    std::vector<HistoryBucket> result;
    result.reserve(buckets.size());
    for (const auto& [index, aggregate] : buckets) {
        HistoryBucket bucket;
        bucket.start = std::chrono::system_clock::time_point(milliseconds(plan.origin + index * plan.width));
        bucket.min = aggregate.min;
        bucket.max = aggregate.max;
        bucket.mean = aggregate.sum / static_cast<double>(aggregate.count);
        bucket.count = static_cast<std::size_t>(aggregate.count);
        result.push_back(bucket);
    }
    return result;
}

// The first sample of the series with a value after `t`, in ms; none when there is none yet.
Result<std::optional<std::int64_t>> next_value_after(sqlite::Statement& next, std::int64_t series, std::int64_t t) {
    next.reset();  // and its bindings
    next.bind(1, series);
    next.bind(2, t);
    auto row = next.step();
    if (!row) return row.error();
    return *row ? std::optional<std::int64_t>(next.integer(0)) : std::nullopt;
}

// The gaps that overlap [from, to]: the samples without a value (their own index, so a month of
// history costs a few lookups) each start one, unless one is open, which lasts to the next
// sample with a value. At most max_gaps, the first ones: an answer stays a bounded size.
constexpr std::size_t max_gaps = 10000;

Result<std::vector<HistoryGap>> gaps_of(sqlite::Connection& db, std::int64_t series, std::int64_t from, std::int64_t to) {
    auto before = db.prepare("SELECT value IS NULL FROM samples WHERE series_id = ?1 AND t < ?2 ORDER BY t DESC LIMIT 1");
    auto starts = db.prepare("SELECT t FROM samples WHERE series_id = ?1 AND value IS NULL AND t >= ?2 AND t <= ?3 ORDER BY t");
    auto next = db.prepare("SELECT t FROM samples WHERE series_id = ?1 AND t > ?2 AND value IS NOT NULL ORDER BY t LIMIT 1");
    if (!before) return before.error();
    if (!starts) return starts.error();
    if (!next) return next.error();
    std::vector<HistoryGap> gaps;
    std::optional<std::int64_t> open_until;  // the end of the last gap found; none: it lasts
    const auto add = [&](std::int64_t start) -> Result<void> {
        auto end = next_value_after(*next, series, start);
        if (!end) return end.error();
        open_until = *end;
        gaps.push_back({std::chrono::system_clock::time_point(milliseconds(start)),
                        *end ? std::optional(std::chrono::system_clock::time_point(milliseconds(**end))) : std::nullopt});
        return {};
    };
    before->bind(1, series);
    before->bind(2, from);
    auto last = before->step();
    if (!last) return last.error();
    if (*last && before->integer(0) != 0) {
        if (auto added = add(from - 1); !added) return added.error();
        gaps.back().start = std::chrono::system_clock::time_point(milliseconds(from));
    }
    starts->bind(1, series);
    starts->bind(2, from);
    starts->bind(3, to);
    while (gaps.size() < max_gaps) {
        auto row = starts->step();
        if (!row) return row.error();
        if (!*row) break;
        const std::int64_t t = starts->integer(0);
        if (!gaps.empty() && (!open_until || t < *open_until)) continue;  // inside the gap already open
        if (auto added = add(t); !added) return added.error();
    }
    return gaps;
}

// The value in force at `from` (HistorySeries::before): the last row before it, if no older
// than `look_back` and holding a value read. A row without a value, or saying nothing was read,
// gives none (the line starts broken: gaps_of opens the gap at `from`).
Result<std::optional<HistoryBefore>> before_of(sqlite::Connection& db, std::int64_t series, std::int64_t from,
                                               std::int64_t look_back) {
    auto statement =
        db.prepare("SELECT t, value, status FROM samples WHERE series_id = ?1 AND t < ?2 AND t >= ?3 ORDER BY t DESC LIMIT 1");
    if (!statement) return statement.error();
    statement->bind(1, series);
    statement->bind(2, from);
    statement->bind(3, from - std::max<std::int64_t>(0, look_back));
    auto row = statement->step();
    if (!row) return row.error();
    if (!*row || statement->is_null(1)) return std::optional<HistoryBefore>{};
    const std::optional<std::string> status =
        statement->is_null(2) ? std::nullopt : std::optional<std::string>(statement->text(2));
    if (!holds_reading(status)) return std::optional<HistoryBefore>{};
    return std::optional(HistoryBefore{std::chrono::system_clock::time_point(milliseconds(statement->integer(0))),
                                       statement->real(1)});
}

struct SeriesRow {
    std::int64_t id = 0;
    std::string parameter;
    std::string unit;
};

Result<std::vector<std::string>> recorded_devices(sqlite::Connection& db) {
    auto statement = db.prepare("SELECT DISTINCT device FROM series ORDER BY device");
    if (!statement) return statement.error();
    std::vector<std::string> devices;
    for (;;) {
        auto row = statement->step();
        if (!row) return row.error();
        if (!*row) return devices;
        devices.push_back(statement->text(0));
    }
}

// The device's series, one per parameter in the order first recorded; of a parameter recorded
// under several units (its profile changed), the latest.
Result<std::vector<SeriesRow>> series_of(sqlite::Connection& db, const std::string& device) {
    auto statement = db.prepare("SELECT id, parameter, unit FROM series WHERE device = ?1 ORDER BY id");
    if (!statement) return statement.error();
    statement->bind(1, std::string_view(device));
    std::vector<SeriesRow> series;
    for (;;) {
        auto row = statement->step();
        if (!row) return row.error();
        if (!*row) return series;
        SeriesRow found{statement->integer(0), statement->text(1), statement->text(2)};
        auto same = std::find_if(series.begin(), series.end(), [&](const SeriesRow& s) { return s.parameter == found.parameter; });
        if (same != series.end()) *same = std::move(found);
        else series.push_back(std::move(found));
    }
}

std::string names_of(const std::vector<SeriesRow>& series) {
    std::vector<std::string> names;
    for (const auto& s : series) names.push_back(s.parameter);
    return fmt::format("{}", fmt::join(names, ", "));
}

Result<std::vector<SeriesRow>> chosen_series(sqlite::Connection& db, const HistoryQuery& query) {
    auto all = series_of(db, query.device);
    if (!all) return all.error();
    if (all->empty()) {
        auto devices = recorded_devices(db);
        if (!devices) return devices.error();
        return make_error(ErrorKind::usage,
                          fmt::format("no history of a device named \"{}\" (devices recorded: {})", query.device,
                                      devices->empty() ? "none yet" : fmt::format("{}", fmt::join(*devices, ", "))));
    }
    if (query.parameters.empty()) return all;
    std::vector<SeriesRow> chosen;
    for (const auto& name : query.parameters) {
        auto found = std::find_if(all->begin(), all->end(), [&](const SeriesRow& s) { return s.parameter == name; });
        if (found == all->end()) {
            return make_error(ErrorKind::usage, fmt::format("device \"{}\" has no history of a parameter named \"{}\" (recorded: {})",
                                                            query.device, name, names_of(*all)));
        }
        chosen.push_back(*found);
    }
    return chosen;
}

}  // namespace

Result<std::vector<HistorySeries>> run_query(sqlite::Connection& db, const HistoryQuery& query) {
    const std::int64_t from = to_ms(query.from);
    const std::int64_t to = to_ms(query.to);
    if (from > to) return make_error(ErrorKind::usage, "the history query's `from` is after its `to`; give from <= to");
    if (query.points == 0 || query.points > max_points) {
        return make_error(ErrorKind::usage, fmt::format("{} points: ask for 1 to {} points per parameter", query.points, max_points));
    }
    auto chosen = chosen_series(db, query);
    if (!chosen) return chosen.error();
    // One read transaction: every series is read from the same snapshot of the file.
    if (auto begun = db.execute("BEGIN"); !begun) return begun.error();
    std::vector<HistorySeries> result;
    for (const auto& series : *chosen) {
        auto buckets = buckets_of(db, series.id, from, to, query.points);
        if (!buckets) {
            (void)db.execute("ROLLBACK");
            return buckets.error();
        }
        auto gaps = gaps_of(db, series.id, from, to);
        if (!gaps) {
            (void)db.execute("ROLLBACK");
            return gaps.error();
        }
        auto before = before_of(db, series.id, from, query.look_back.count());
        if (!before) {
            (void)db.execute("ROLLBACK");
            return before.error();
        }
        result.push_back({series.parameter, series.unit, std::move(*buckets), std::move(*gaps), *before});
    }
    (void)db.execute("COMMIT");
    return result;
}

Result<std::vector<AuditRecord>> run_audit_query(sqlite::Connection& db, const AuditQuery& query) {
    std::vector<AuditRecord> records;
    auto tables = db.query_integer("SELECT count(*) FROM sqlite_schema WHERE type = 'table' AND name = 'writes'");
    if (!tables) return tables.error();
    if (*tables == 0) return records;
    auto statement = db.prepare(
        "SELECT t, front, peer, user, device, parameter, old_value, new_value, outcome FROM writes "
        "WHERE t >= ?1 AND t <= ?2 AND (?3 = '' OR device = ?3) ORDER BY t DESC, id DESC LIMIT ?4");
    if (!statement) return statement.error();
    const auto ms = [](std::chrono::system_clock::time_point time) -> std::int64_t {
        return std::chrono::duration_cast<std::chrono::milliseconds>(time.time_since_epoch()).count();
    };
    statement->bind(1, ms(query.from));
    statement->bind(2, ms(query.to));
    statement->bind(3, std::string_view(query.device));
    statement->bind(4, static_cast<std::int64_t>(query.limit));
    for (;;) {
        auto row = statement->step();
        if (!row) return row.error();
        if (!*row) break;
        AuditRecord record;
        record.time = std::chrono::system_clock::time_point(std::chrono::milliseconds(statement->integer(0)));
        record.origin = {statement->text(1), statement->text(2), statement->text(3)};
        record.device = statement->text(4);
        record.parameter = statement->text(5);
        record.old_value = statement->text(6);
        record.new_value = statement->text(7);
        record.outcome = statement->text(8);
        records.push_back(std::move(record));
    }
    return records;
}

}  // namespace history
}  // namespace loopwire::gateway
