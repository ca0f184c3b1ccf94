#include "gateway/postgres_history_schema.hpp"

#include <string>

#include <fmt/format.h>

namespace loopwire::gateway::postgres_history {
namespace {

// The advisory lock every gateway takes before changing the schema or its partitions, so that
// two of them creating the same table at once do not fail on each other ("LWHi").
constexpr const char* schema_lock = "SELECT pg_advisory_xact_lock(1280788585)";

// Every table and index, each made only where missing: a first gateway makes them all, and a
// gateway that finds one gone (dropped under it by hand) makes it again on its next connect or
// failed batch (history_forwarder.cpp), rather than failing until its connection breaks.
constexpr const char* create_tables = R"sql(
CREATE TABLE IF NOT EXISTS loopwire_series(
  id bigserial PRIMARY KEY,
  gateway text NOT NULL,
  device text NOT NULL,
  parameter text NOT NULL,
  unit text NOT NULL,
  UNIQUE(gateway, device, parameter, unit));
CREATE TABLE IF NOT EXISTS loopwire_samples(
  series_id bigint NOT NULL,
  t bigint NOT NULL,
  value double precision,
  text text,
  status text,
  PRIMARY KEY(series_id, t)) PARTITION BY RANGE (t);
CREATE TABLE IF NOT EXISTS loopwire_minutes(
  series_id bigint NOT NULL,
  minute bigint NOT NULL,
  lo double precision NOT NULL,
  hi double precision NOT NULL,
  total double precision NOT NULL,
  n bigint NOT NULL,
  PRIMARY KEY(series_id, minute));
CREATE TABLE IF NOT EXISTS loopwire_writes(
  gateway text NOT NULL,
  local_id bigint NOT NULL,
  t bigint NOT NULL,
  time timestamptz NOT NULL,
  front text NOT NULL,
  peer text NOT NULL,
  user_name text NOT NULL,
  device text NOT NULL,
  parameter text NOT NULL,
  old_value text NOT NULL,
  new_value text NOT NULL,
  outcome text NOT NULL,
  PRIMARY KEY(gateway, t, local_id));
)sql";

// Version 2: the samples without a value (special states, missed replies) indexed apart, so a
// query finds the gaps of a month without reading the month: the local file has the same index.
constexpr const char* create_gaps_index =
    "CREATE INDEX IF NOT EXISTS loopwire_samples_gaps ON loopwire_samples(series_id, t) WHERE value IS NULL";

// What Grafana, psql and a report read: one row a sample with its time as a timestamp, its
// gateway, device, parameter and unit by name, and the word "ok" where the samples say NULL.
// `t` (ms since the epoch) stays beside `time`: a query on `t` is pruned to the day partitions
// it spans and uses their primary keys, which a filter on the computed `time` cannot
// (docs/grafana.md). Replaced on every connect, so a historian made by an earlier loopwire gets it.
constexpr const char* create_values_view = R"sql(
CREATE OR REPLACE VIEW loopwire_values AS
SELECT to_timestamp(s.t / 1000.0) AS time, s.t, n.gateway, n.device, n.parameter, n.unit, s.value,
       coalesce(s.status, 'ok') AS status, s.text
FROM loopwire_samples s JOIN loopwire_series n ON n.id = s.series_id
)sql";

// Runs `steps` in one transaction under the schema lock; rolls back on failure.
template <typename Steps>
Result<void> locked(postgres::Connection& db, Steps steps) {
    if (auto begun = db.run("BEGIN"); !begun) return begun.error();
    Result<void> done = db.run(schema_lock);
    if (done) done = steps();
    if (done) done = db.run("COMMIT");
    if (!done) (void)db.execute("ROLLBACK");
    return done;
}

std::string partition_name(std::int64_t day) {
    const auto date = std::chrono::year_month_day(std::chrono::sys_days(std::chrono::days(day)));
    return fmt::format("loopwire_samples_{:04}{:02}{:02}", static_cast<int>(date.year()),
                       static_cast<unsigned>(date.month()), static_cast<unsigned>(date.day()));
}

}  // namespace

std::int64_t day_of(std::int64_t ms) { return ms / day_ms - ((ms % day_ms != 0 && ms < 0) ? 1 : 0); }

Result<void> migrate(postgres::Connection& db) {
    return locked(db, [&]() -> Result<void> {
        if (auto made = db.execute("CREATE TABLE IF NOT EXISTS loopwire_schema_version(version integer NOT NULL)"); !made) {
            return made.error();
        }
        auto version = db.execute("SELECT max(version) FROM loopwire_schema_version");
        if (!version) return version.error();
        const long long found = version->is_null(0, 0) ? 0 : version->integer(0, 0);
        if (found > schema_version) {
            return make_error(ErrorKind::usage,
                              fmt::format("{}: the history tables are of schema version {}, written by a newer loopwire; "
                                          "this one knows version {}: upgrade this gateway, or forward to another database",
                                          db.server(), found, schema_version));
        }
        if (auto made = db.run(create_tables); !made) return made.error();
        if (auto made = db.run(create_gaps_index); !made) return made.error();
        if (auto made = db.run(create_values_view); !made) return made.error();
        if (found == 0) return db.run(fmt::format("INSERT INTO loopwire_schema_version(version) VALUES ({})", schema_version));
        if (found < schema_version) return db.run(fmt::format("UPDATE loopwire_schema_version SET version = {}", schema_version));
        return {};
    });
}

Result<void> ensure_partitions(postgres::Connection& db, const std::vector<std::int64_t>& days) {
    return locked(db, [&]() -> Result<void> {
        for (const std::int64_t day : days) {
            const std::string sql =
                fmt::format("CREATE TABLE IF NOT EXISTS {} PARTITION OF loopwire_samples FOR VALUES FROM ({}) TO ({})",
                            partition_name(day), day * day_ms, (day + 1) * day_ms);
            if (auto made = db.execute(sql); !made) return made.error();
        }
        return {};
    });
}

Result<int> drop_partitions_before(postgres::Connection& db, std::int64_t cutoff_ms) {
    int dropped = 0;
    auto done = locked(db, [&]() -> Result<void> {
        // The partitions' own names carry their day: no need to parse the bounds' expressions.
        auto children = db.execute(
            "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid "
            "WHERE i.inhparent = 'loopwire_samples'::regclass");
        if (!children) return children.error();
        for (int row = 0; row < children->rows(); ++row) {
            const std::string name = children->text(row, 0);
            for (std::int64_t day = day_of(cutoff_ms) - 1; day >= day_of(cutoff_ms) - 3660; --day) {
                if (name != partition_name(day)) continue;
                if (auto gone = db.execute(fmt::format("DROP TABLE {}", name)); !gone) return gone.error();
                ++dropped;
                break;
            }
        }
        const postgres::Parameters minute{std::to_string(day_of(cutoff_ms) * day_ms / 60000)};
        if (auto gone = db.run("DELETE FROM loopwire_minutes WHERE minute < $1", minute); !gone) return gone.error();
        // The audit's rows are few: deleted by row, at the same day's bound as the samples.
        return db.run("DELETE FROM loopwire_writes WHERE t < $1", {std::to_string(day_of(cutoff_ms) * day_ms)});
    });
    if (!done) return done.error();
    return dropped;
}

}  // namespace loopwire::gateway::postgres_history
