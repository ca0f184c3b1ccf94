#pragma once
// What the HTTP API asks of the history (gateway/history_reader.hpp answers it): downsampled series
// of the values the polls recorded, so the API depends on the question, not on SQLite.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "gateway/write_audit.hpp"

namespace loopwire::gateway {

struct HistoryQuery {
    std::string device;                   // the configured device name
    // Another gateway forwarding to the same PostgreSQL historian ([history] forward_to);
    // empty, or this gateway's own name: this gateway's own history, from its file.
    std::string gateway;
    std::vector<std::string> parameters;  // profile names; empty: every parameter recorded
    std::chrono::system_clock::time_point from;
    std::chrono::system_clock::time_point to;
    std::size_t points = 500;             // at most this many buckets per parameter
    // How far before `from` the value in force there (HistorySeries::before) is looked for.
    // Every value still read is written again each heartbeat, so a last row older than a
    // heartbeat or two means nothing was recorded since (the gateway was stopped): not a value
    // known to hold at `from`. The history store sets twice its own heartbeat; this default is
    // twice the default heartbeat (60 s).
    std::chrono::milliseconds look_back{120000};
};

// One bucket of a downsampled series: min and max keep the spikes a mean would hide.
struct HistoryBucket {
    std::chrono::system_clock::time_point start;
    double min = 0;
    double max = 0;
    double mean = 0;
    std::size_t count = 0;  // samples with a value in the bucket; buckets with none are left out
};

// A time the parameter had no value: from a sample without one (no reply, a special state,
// stale) to the next sample with one. Values are recorded on change, so between two samples
// with values the first one held: a chart draws steps, and breaks its line only in a gap.
struct HistoryGap {
    std::chrono::system_clock::time_point start;  // the query's `from` for a gap that began before it
    std::optional<std::chrono::system_clock::time_point> end;  // none: it lasts (up to now)
};

// The value in force at the query's `from`: the last row recorded before it, when that row
// holds a value that was read (not a row saying nothing was read, nor a special state) and is
// no older than the query's look_back. Values are recorded on change, so without it a value
// that held since before `from` has nothing to draw until the first row inside the range.
// Not a bucket: the buckets' statistics stay those of the rows inside [from, to].
struct HistoryBefore {
    std::chrono::system_clock::time_point time;  // when the row was recorded (before `from`)
    double value = 0;
};

struct HistorySeries {
    std::string parameter;
    std::string unit;
    std::vector<HistoryBucket> buckets;  // in time order
    std::vector<HistoryGap> gaps;        // in time order; the gaps that overlap the query's range
    std::optional<HistoryBefore> before = std::nullopt;  // none: no value known to hold at `from`
};

// The forwarding to a PostgreSQL historian (gateway/history_forwarder.hpp), for GET /metrics.
struct ForwardStats {
    std::uint64_t waiting_rows = 0;     // in the outbox when last looked at
    std::uint64_t forwarded_total = 0;  // rows PostgreSQL acknowledged since start
    double oldest_waiting_seconds = 0;  // age of the oldest waiting row; 0 when none wait
    std::uint64_t errors_total = 0;     // failed attempts (connects, batches)
};

class HistorySource {
public:
    virtual ~HistorySource() = default;
    // Runs `work`, which may block on the database (a query, the historian's answer), where
    // blocking holds up nothing else: the history reader's thread (gateway/history_reader.hpp),
    // never the loop the HTTP API serves on (the engine's, with the polls), nor the writer that
    // commits the history. Here, at once, for a source without a thread.
    // From any thread; `work` runs once, in the order given.
    virtual void run_blocking(std::function<void()> work) const { work(); }
    // The error says what was wrong with the query (unknown device or parameter, from after to).
    virtual Result<std::vector<HistorySeries>> query(const HistoryQuery& query) const = 0;
    // Rows committed since the gateway started (GET /metrics).
    virtual std::uint64_t rows_written() const = 0;
    // None when the history is not forwarded ([history] forward_to absent).
    virtual std::optional<ForwardStats> forward_stats() const { return std::nullopt; }
    // The gateways whose history the shared historian holds, sorted; ErrorKind::usage when
    // there is no historian ([history] forward_to absent).
    virtual Result<std::vector<std::string>> historian_gateways() const {
        return make_error(ErrorKind::usage, "no historian: the history is forwarded nowhere ([history] forward_to absent)");
    }
    // The audit of writes (gateway/write_audit.hpp), newest first; ErrorKind::usage where no
    // audit is kept.
    virtual Result<std::vector<AuditRecord>> audit(const AuditQuery& /*query*/) const {
        return make_error(ErrorKind::usage, "no audit of writes is kept here");
    }
};

}  // namespace loopwire::gateway
