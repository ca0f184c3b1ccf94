#pragma once
// The rows of one forwarder batch (gateway/history_forwarder.hpp) as they travel to the
// PostgreSQL historian: the samples in COPY's binary format (numbers as their bytes: the server
// parses no text, which is most of a text COPY's cost), and their per-minute rollup computed
// here, so that a batch whose rows are all new (the usual case) goes in by one COPY straight into
// the samples and one small upsert of its minutes, with no server-side pass over the rows again.
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>

#include "gateway/postgres_database.hpp"

namespace loopwire::gateway {

// A minute's rollup as loopwire_minutes holds it; lo and hi order NaN above every number, as
// PostgreSQL's min() and max() of float8 do, so the two ways of computing it agree.
struct MinuteRollup {
    double lo = 0;
    double hi = 0;
    double total = 0;
    std::int64_t n = 0;
    void add(double value);
};

class ForwardBatch {
public:
    using MinuteKey = std::pair<std::int64_t, std::int64_t>;  // the historian's series id, the minute

    // A sample of the historian's series `series` at `t` (ms since the epoch); a value-less one
    // (a missed reply, a special state) has no part in the minutes.
    ForwardBatch();
    void add(std::int64_t series, std::int64_t t, std::optional<double> value, std::optional<std::string_view> text,
             std::optional<std::string_view> status);

    std::uint64_t rows() const { return rows_; }
    // COPY ... (FORMAT binary) data, whole: a tuple a sample (series, t, value, text, status).
    std::string copy_data() const;
    const std::set<std::int64_t>& days() const { return days_; }  // the UTC days (since the epoch) of the rows
    const std::map<MinuteKey, MinuteRollup>& minutes() const { return minutes_; }
    // The minutes as six array parameters (series, minute, lo, hi, total, n) for one upsert.
    postgres::Parameters minute_columns() const;

private:
    std::uint64_t rows_ = 0;
    std::string copy_;  // the header and the tuples so far
    std::set<std::int64_t> days_;
    std::map<MinuteKey, MinuteRollup> minutes_;
};

// PostgreSQL's text for a double, its own words for the non-finite ones, appended to `out`.
void append_float8(std::string& out, double value);

}  // namespace loopwire::gateway
