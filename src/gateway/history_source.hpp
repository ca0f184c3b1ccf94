#pragma once
// What the HTTP API asks of the history store (gateway/history_store.hpp): downsampled series
// of the values the polls recorded, so the API depends on the question, not on SQLite.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/result.hpp"

namespace loopwire::gateway {

struct HistoryQuery {
    std::string device;                   // the configured device name
    std::vector<std::string> parameters;  // profile names; empty: every parameter recorded
    std::chrono::system_clock::time_point from;
    std::chrono::system_clock::time_point to;
    std::size_t points = 500;             // at most this many buckets per parameter
};

// One bucket of a downsampled series: min and max keep the spikes a mean would hide.
struct HistoryBucket {
    std::chrono::system_clock::time_point start;
    double min = 0;
    double max = 0;
    double mean = 0;
    std::size_t count = 0;  // samples with a value in the bucket; buckets with none are left out
};

struct HistorySeries {
    std::string parameter;
    std::string unit;
    std::vector<HistoryBucket> buckets;  // in time order
};

class HistorySource {
public:
    virtual ~HistorySource() = default;
    // The error says what was wrong with the query (unknown device or parameter, from after to).
    virtual Result<std::vector<HistorySeries>> query(const HistoryQuery& query) const = 0;
    // Rows committed since the gateway started (GET /metrics).
    virtual std::uint64_t rows_written() const = 0;
};

}  // namespace loopwire::gateway
