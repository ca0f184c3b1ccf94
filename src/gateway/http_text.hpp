#pragma once
// The small texts of the HTTP API: times in ISO 8601, URL query strings, the history query
// they carry and its CSV form.
#include <chrono>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/result.hpp"
#include "gateway/history_source.hpp"
#include "gateway/write_audit.hpp"

namespace loopwire::gateway {

// "2026-12-02T01:39:56.123Z": UTC, to the millisecond.
std::string iso_time(std::chrono::system_clock::time_point time);

// "2026-12-02T01:39:56Z", with optional fractions of a second, or an offset ("+01:00") instead
// of Z. A time without a zone is refused: it would be read in some zone the caller did not mean,
// as is one outside the years below.
constexpr int earliest_year = 1700;
constexpr int latest_year = 2200;
std::optional<std::chrono::system_clock::time_point> parse_iso_time(std::string_view text);

// %XX and '+' (a space, in a query) decoded; none when a % is not followed by two hex digits.
std::optional<std::string> percent_decode(std::string_view text, bool plus_is_space = false);
// Every byte but letters, digits and "-._:," as %XX: a value for a query string.
std::string percent_encode(std::string_view text);

// "a=1&b=two": each name's (last) value, decoded; names or values that do not decode are left out.
std::map<std::string, std::string> parse_query(std::string_view query);

struct ParsedHistoryQuery {
    HistoryQuery query;
    bool csv = false;
};

// GET /api/history's query: device (required), gateway (another gateway's history in the shared
// PostgreSQL historian; default this one's), parameters=a,b (default every one recorded),
// from and to in ISO 8601, as "now" or as a time before now ("-1h", "-7d"; default the last hour
// up to `now`), points 1..10000 (default 500), format=json|csv. The error says which is wrong and
// how it should look.
Result<ParsedHistoryQuery> history_query(std::string_view query, std::chrono::system_clock::time_point now);

// parameter,unit,time,min,max,mean,count,kind,until with a header line, each series' rows in
// time order, `kind` saying what a row is:
// - before: the value in force at `from` (HistorySeries::before), recorded at `time`, before
//   `from`; min, max and mean hold it, count is empty: it is no bucket;
// - bucket: min, max, mean and count of the rows from `time` to the next bucket;
// - gap: no value from `time` until `until` (empty while it lasts); no figures.
std::string history_csv(const std::vector<HistorySeries>& series);

// What a series holds, in time order: the value in force at `from` first, then its buckets and
// gaps as they come (a gap and a bucket starting together: the bucket first, as its values came
// then). For the CSV above and `loopwire history`'s table.
struct HistoryRowVisitor {
    std::function<void(const HistoryBefore&)> before;
    std::function<void(const HistoryBucket&)> bucket;
    std::function<void(const HistoryGap&)> gap;
};
void visit_in_time_order(const HistorySeries& series, const HistoryRowVisitor& visit);

// GET /api/audit's query: from and to as the history's (default the last 24 hours up to
// `now`), device (default every one), limit 1..100000 (default 1000). The error says which is
// wrong and how it should look.
Result<AuditQuery> audit_query(std::string_view query, std::chrono::system_clock::time_point now);

// The audit's records as JSON ({"records": [{"time", "front", "peer", "user", "device",
// "parameter", "old_value", "new_value", "outcome"}, ...]}) and as CSV with a header line of the
// same names, in the order given.
std::string audit_json(const std::vector<AuditRecord>& records);
std::string audit_csv(const std::vector<AuditRecord>& records);

}  // namespace loopwire::gateway
