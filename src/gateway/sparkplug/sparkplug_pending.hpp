#pragma once
// Where store and forward keeps what the node could not send ([sparkplug] store_and_forward), so
// that it survives a restart of the gateway while the broker is away: in the gateway's history
// file ([history] database), table `sparkplug_pending`, one row a metric of a DDATA the node
// would have sent (its device, metric name, sample and the time the DDATA was made).
//
// Why a table of its own rather than the history's samples read back since the last DDATA sent:
// the samples are each parameter's changes and heartbeats, not the node's messages. A metric is
// not a parameter (a bit field is one metric a bit), a DDATA carries what a turn coalesced, nulls
// with their Quality, and the births decide which values are already told; rebuilding that from
// the samples would be a second, lossy translation. The table holds exactly the metrics the node
// would have sent, written by the history's writer thread (HistoryStore::run_in_writer: the
// engine's loop only queues), read once when the node starts and emptied once they are
// forwarded. Without [history] the queue stays in memory only (gateway --check says so).
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "gateway/sparkplug/sparkplug_payloads.hpp"

namespace loopwire::gateway {

class HistoryStore;

// One metric of a DDATA kept to forward.
struct PendingMetric {
    std::uint64_t made_at = 0;  // ms since the epoch: when the DDATA would have been sent
    std::string device;
    std::string metric;  // its name (aliases follow from the configuration)
    sparkplug::MetricSample sample;
};

// How the node keeps its store beside memory; empty functions: in memory only.
struct SparkplugPending {
    std::vector<PendingMetric> loaded;                    // what the last run kept and did not forward, in order
    std::function<void(std::vector<PendingMetric>)> add;  // queued, never waits
    std::function<void()> clear;                          // queued after what was added before
    std::function<void(std::uint64_t)> forget_before;     // the rows made before this time (ms)
};

// Reads what the file keeps (none when the table is empty or missing), on the caller's thread.
Result<std::vector<PendingMetric>> load_sparkplug_pending(const std::filesystem::path& database);
// The add, clear and replace that go through `store`'s writer thread (which must outlive them).
SparkplugPending sparkplug_pending_in(HistoryStore& store);

}  // namespace loopwire::gateway
