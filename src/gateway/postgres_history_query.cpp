#include "gateway/postgres_history_query.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "gateway/history_store.hpp"
#include "profile/profile.hpp"
#include "profile/request_planner.hpp"

namespace loopwire::gateway::postgres_history {
namespace {

using std::chrono::milliseconds;
using TimePoint = std::chrono::system_clock::time_point;

constexpr std::size_t max_points = 10000;
constexpr std::size_t max_gaps = 10000;  // as the local query: an answer stays a bounded size

std::int64_t to_ms(TimePoint time) { return std::chrono::duration_cast<milliseconds>(time.time_since_epoch()).count(); }
TimePoint from_ms(long long ms) { return TimePoint(milliseconds(ms)); }
std::string number(std::int64_t n) { return std::to_string(n); }

struct Series {
    std::string id;
    std::string parameter;
    std::string unit;
};

// The parameter `name` stands for among the device's series: itself when one is so named, else
// what it is an alias (PV) or mnemonic of in the profile that gives it a meaning the device has
// a series of. The historian knows no device's profile, and the profiles give an alias different
// meanings (PV is the TC10's measured_value, the AC20's carbon_potential): the device's own
// parameters tell which one it is. As written when none does (refused then, by that name).
std::string parameter_named(const std::string& name, const std::vector<Series>& all) {
    const auto has = [&all](const std::string& parameter) {
        return std::any_of(all.begin(), all.end(), [&](const Series& s) { return s.parameter == parameter; });
    };
    if (has(name)) return name;
    std::optional<std::string> meant;
    for (const auto& id : device::builtin_profile_ids()) {
        auto profile = device::builtin_profile(id);
        if (!profile) continue;
        auto resolved = device::resolve_parameters(**profile, {name});
        if (!resolved || resolved->size() != 1 || !has(resolved->front()->name)) continue;
        if (meant && *meant != resolved->front()->name) return name;  // two meanings the device has: not guessed
        meant = resolved->front()->name;
    }
    return meant.value_or(name);
}

// The gateway's series of the device, narrowed to the parameters asked for (all when none).
Result<std::vector<Series>> chosen_series(postgres::Connection& db, const std::string& gateway, const HistoryQuery& query) {
    auto rows = db.execute("SELECT id, parameter, unit FROM loopwire_series WHERE gateway = $1 AND device = $2 ORDER BY parameter",
                           {gateway, query.device});
    if (!rows) return rows.error();
    if (rows->rows() == 0) {
        return make_error(ErrorKind::usage, fmt::format("the historian has no device \"{}\" of gateway \"{}\"", query.device, gateway));
    }
    std::vector<Series> all;
    for (int i = 0; i < rows->rows(); ++i) all.push_back({rows->text(i, 0), rows->text(i, 1), rows->text(i, 2)});
    if (query.parameters.empty()) return all;
    std::vector<Series> chosen;
    for (const auto& name : query.parameters) {
        const std::string parameter = parameter_named(name, all);
        const auto found = std::find_if(all.begin(), all.end(), [&](const Series& s) { return s.parameter == parameter; });
        if (found == all.end()) {
            return make_error(ErrorKind::usage, fmt::format("device \"{}\" of gateway \"{}\" has no parameter \"{}\" in the historian",
                                                            query.device, gateway, name));
        }
        chosen.push_back(*found);
    }
    return chosen;
}

// Grouped on the server: only the buckets travel. Buckets of whole minutes (plan_buckets) read
// the minutes wholly inside [from, to] from the rollup, and only the minutes cut by `from` or
// `to` from the samples, as the local query does: a month of one-second samples is 43,200
// minutes to add up rather than 2.6 million samples. Each part gives (bucket, lo, hi, total, n);
// the bounds are numbers of ours, written into the text.
std::string buckets_sql(const BucketPlan& plan, std::int64_t from, std::int64_t to) {
    const auto samples = [](std::int64_t first, std::int64_t last) {
        return fmt::format(
            "SELECT (t - $2) / $3 AS bucket, value AS lo, value AS hi, value AS total, 1::bigint AS n FROM loopwire_samples "
            "WHERE series_id = $1 AND t >= {} AND t <= {} AND value IS NOT NULL",
            first, last);
    };
    std::string parts = samples(from, to);
    if (const MinuteSpan whole = whole_minutes(from, to); plan.minutes && whole.first < whole.end) {
        parts = fmt::format(
            "{} UNION ALL SELECT (minute * 60000 - $2) / $3, lo, hi, total, n FROM loopwire_minutes "
            "WHERE series_id = $1 AND minute >= {} AND minute < {} UNION ALL {}",
            samples(from, whole.first * 60000 - 1), whole.first, whole.end, samples(whole.end * 60000, to));
    }
    return fmt::format("SELECT bucket, min(lo), max(hi), sum(total) / sum(n), sum(n) FROM ({}) parts GROUP BY 1 ORDER BY 1",
                       parts);
}

Result<std::vector<HistoryBucket>> buckets_of(postgres::Connection& db, const Series& series, std::int64_t from, std::int64_t to,
                                              std::size_t points) {
    const BucketPlan plan = plan_buckets(from, to, points);
    auto rows = db.execute(buckets_sql(plan, from, to), {series.id, number(plan.origin), number(plan.width)});
    if (!rows) return rows.error();
    std::vector<HistoryBucket> buckets;
    for (int i = 0; i < rows->rows(); ++i) {
        HistoryBucket bucket;
        bucket.start = from_ms(plan.origin + rows->integer(i, 0) * plan.width);
        bucket.min = std::stod(rows->text(i, 1));
        bucket.max = std::stod(rows->text(i, 2));
        bucket.mean = std::stod(rows->text(i, 3));
        bucket.count = static_cast<std::size_t>(rows->integer(i, 4));
        buckets.push_back(bucket);
    }
    return buckets;
}

// The first sample with a value after `t`; none while the gap lasts.
Result<std::optional<long long>> next_value_after(postgres::Connection& db, const Series& series, std::int64_t t) {
    auto row = db.execute("SELECT min(t) FROM loopwire_samples WHERE series_id = $1 AND t > $2 AND value IS NOT NULL",
                          {series.id, number(t)});
    if (!row) return row.error();
    if (row->is_null(0, 0)) return std::optional<long long>{};
    return std::optional<long long>(row->integer(0, 0));
}

// The same gaps as the local query (history_query.cpp): a sample without a value opens one,
// the next sample with a value closes it; one open at `from` starts there.
Result<std::vector<HistoryGap>> gaps_of(postgres::Connection& db, const Series& series, std::int64_t from, std::int64_t to) {
    std::vector<HistoryGap> gaps;
    std::optional<long long> open_until;
    const auto add = [&](std::int64_t start, std::int64_t shown) -> Result<void> {
        auto end = next_value_after(db, series, start);
        if (!end) return end.error();
        open_until = *end;
        gaps.push_back({from_ms(shown), *end ? std::optional(from_ms(**end)) : std::nullopt});
        return {};
    };
    auto before = db.execute("SELECT value IS NULL FROM loopwire_samples WHERE series_id = $1 AND t < $2 ORDER BY t DESC LIMIT 1",
                             {series.id, number(from)});
    if (!before) return before.error();
    if (before->rows() == 1 && before->text(0, 0) == "t") {
        if (auto added = add(from - 1, from); !added) return added.error();
    }
    auto starts = db.execute(
        "SELECT t FROM loopwire_samples WHERE series_id = $1 AND value IS NULL AND t >= $2 AND t <= $3 ORDER BY t LIMIT $4",
        // Bounded: the gaps a reply holds are bounded, and most rows without a value fall in a
        // gap already open; past this many, the last gaps of a very broken range are left out.
        {series.id, number(from), number(to), std::to_string(max_gaps * 4)});
    if (!starts) return starts.error();
    for (int i = 0; i < starts->rows() && gaps.size() < max_gaps; ++i) {
        const std::int64_t t = starts->integer(i, 0);
        if (!gaps.empty() && (!open_until || t < *open_until)) continue;  // inside the gap already open
        if (auto added = add(t, t); !added) return added.error();
    }
    return gaps;
}

// The value in force at `from`, as the local query finds it (history_query.cpp): the last row
// before it, no older than `look_back`, when it holds a value read.
Result<std::optional<HistoryBefore>> before_of(postgres::Connection& db, const Series& series, std::int64_t from,
                                               std::int64_t look_back) {
    auto row = db.execute(
        "SELECT t, value, status FROM loopwire_samples WHERE series_id = $1 AND t < $2 AND t >= $3 ORDER BY t DESC LIMIT 1",
        {series.id, number(from), number(from - std::max<std::int64_t>(0, look_back))});
    if (!row) return row.error();
    if (row->rows() == 0 || row->is_null(0, 1)) return std::optional<HistoryBefore>{};
    const std::optional<std::string> status = row->is_null(0, 2) ? std::nullopt : std::optional<std::string>(row->text(0, 2));
    if (!holds_reading(status)) return std::optional<HistoryBefore>{};
    return std::optional(HistoryBefore{from_ms(row->integer(0, 0)), std::stod(row->text(0, 1))});
}

}  // namespace

Result<std::vector<HistorySeries>> run_query(postgres::Connection& db, const std::string& gateway, const HistoryQuery& query) {
    const std::int64_t from = to_ms(query.from);
    const std::int64_t to = to_ms(query.to);
    if (from > to) return make_error(ErrorKind::usage, "the history query's `from` is after its `to`; give from <= to");
    if (query.points == 0 || query.points > max_points) {
        return make_error(ErrorKind::usage, fmt::format("{} points: ask for 1 to {} points per parameter", query.points, max_points));
    }
    auto chosen = chosen_series(db, gateway, query);
    if (!chosen) return chosen.error();
    // One snapshot for every series, as the local query reads one.
    if (auto begun = db.run("BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY"); !begun) return begun.error();
    std::vector<HistorySeries> result;
    Result<void> done;
    for (const auto& series : *chosen) {
        auto buckets = buckets_of(db, series, from, to, query.points);
        if (!buckets) {
            done = buckets.error();
            break;
        }
        auto gaps = gaps_of(db, series, from, to);
        if (!gaps) {
            done = gaps.error();
            break;
        }
        auto before = before_of(db, series, from, query.look_back.count());
        if (!before) {
            done = before.error();
            break;
        }
        result.push_back({series.parameter, series.unit, std::move(*buckets), std::move(*gaps), *before});
    }
    (void)db.run(done ? "COMMIT" : "ROLLBACK");
    if (!done) return done.error();
    return result;
}

}  // namespace loopwire::gateway::postgres_history
