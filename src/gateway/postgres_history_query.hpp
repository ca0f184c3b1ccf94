#pragma once
// The history of any gateway that forwards to the shared PostgreSQL historian, asked as the
// local file is (gateway/history_source.hpp): the same buckets (plan_buckets) and the same
// gaps, computed from loopwire_samples and, for buckets of whole minutes, the per-minute rollup
// (loopwire_minutes). /api/history?gateway=NAME asks here for a gateway
// other than this one; this gateway's own history is read from its file, which also holds
// the rows still waiting to be forwarded.
#include <string>
#include <vector>

#include "common/result.hpp"
#include "gateway/history_source.hpp"
#include "gateway/postgres_database.hpp"

namespace loopwire::gateway::postgres_history {

Result<std::vector<HistorySeries>> run_query(postgres::Connection& db, const std::string& gateway, const HistoryQuery& query);

}  // namespace loopwire::gateway::postgres_history
