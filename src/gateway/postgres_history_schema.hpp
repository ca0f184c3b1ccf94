#pragma once
// The fleet history's tables in PostgreSQL, shared by every gateway that forwards to one
// database (gateway/history_forwarder.hpp):
//   loopwire_schema_version(version): one row, the schema's version; a newer one is refused.
//   loopwire_series(id, gateway, device, parameter, unit): the gateway's [gateway] name is part
//     of every series, so many gateways' devices of the same name stay apart.
//   loopwire_samples(series_id, t, value, text, status), key (series_id, t): t in ms since the
//     epoch as in the SQLite file; partitioned by range of t, one partition a UTC day
//     (loopwire_samples_YYYYMMDD), created ahead by the forwarder and dropped whole once older
//     than `keep` (cheaper than deleting rows, and no vacuum debt). Partitions are shared by
//     every gateway, and each drops those older than its own `keep`: the historian keeps the
//     shortest `keep` of the gateways that forward to it.
//   loopwire_minutes(series_id, minute, lo, hi, total, n): the per-minute rollup, as in SQLite,
//     upserted in the same statement that inserts the samples, from the rows that statement
//     really inserted: a batch sent twice (a crash after PostgreSQL committed, before the
//     outbox was cleared) adds neither samples nor minutes twice.
//   loopwire_samples_gaps (version 2): the samples without a value, indexed apart for the gaps.
//   loopwire_writes(gateway, local_id, t, time, front, peer, user_name, device, parameter,
//     old_value, new_value, outcome), key (gateway, t, local_id): the audit of writes and
//     reloads (gateway/write_audit.hpp), a row of the gateway's file's `writes` table each; a row
//     sent twice is there once. Added to version 2 without a new version: a table no earlier
//     gateway reads, which would otherwise refuse a historian a newer one had connected to.
#include <chrono>
#include <cstdint>
#include <vector>

#include "common/result.hpp"
#include "gateway/postgres_database.hpp"

namespace loopwire::gateway::postgres_history {

constexpr int schema_version = 2;
constexpr std::int64_t day_ms = 24LL * 60 * 60 * 1000;

// Creates the tables, or checks they are of this version and makes any that are missing (dropped
// by hand); refuses a newer schema with a message saying which version wrote it. Safe with many
// gateways migrating at once (an advisory lock).
Result<void> migrate(postgres::Connection& db);

// The UTC day a time in ms since the epoch falls in (days since the epoch).
std::int64_t day_of(std::int64_t ms);

// Creates the partitions of these days (days since the epoch) if missing.
Result<void> ensure_partitions(postgres::Connection& db, const std::vector<std::int64_t>& days);

// Drops the day partitions that end at or before `cutoff_ms`, and the minutes before it;
// returns the partitions dropped.
Result<int> drop_partitions_before(postgres::Connection& db, std::int64_t cutoff_ms);

}  // namespace loopwire::gateway::postgres_history
