#pragma once
// The history's downsampled series: one parameter over [from, to] cut into at most `points`
// buckets with min, max and mean (gateway/history_source.hpp).
#include <vector>

#include "common/result.hpp"
#include "gateway/history_source.hpp"
#include "gateway/history_store.hpp"
#include "gateway/sqlite_database.hpp"
#include "gateway/write_audit.hpp"

namespace loopwire::gateway::history {

// The most buckets one query may ask for: a chart has at most a few thousand pixels.
constexpr std::size_t max_points = 10000;

Result<std::vector<HistorySeries>> run_query(sqlite::Connection& db, const HistoryQuery& query);

// The audit's records the query asks for, newest first (a file of a loopwire before the audit
// has none).
Result<std::vector<AuditRecord>> run_audit_query(sqlite::Connection& db, const AuditQuery& query);

}  // namespace loopwire::gateway::history
