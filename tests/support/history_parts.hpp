#pragma once
// The history's parts as the gateway wires them (gateway.cpp: the store, the forwarder when
// forwarding, the reader), for the tests: no thread unless a test starts one (the writer's,
// store->start()) or asks for one (the forwarder's and the reader's options), so that a test on
// virtual time writes, forwards and asks itself. Its calls are the parts' own, gathered.
#include <algorithm>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "common/result.hpp"
#include "gateway/history_forwarder.hpp"
#include "gateway/history_reader.hpp"
#include "gateway/history_store.hpp"

namespace loopwire::testing {

struct HistoryPartsOptions : gateway::HistoryOptions {
    std::optional<gateway::ForwardOptions> forward;  // [history] forward_to
    bool reader_thread = false;
    // The historian reader's bounds; none: the gateway's (a connect within 3 s at most).
    std::optional<gateway::HistorianLimits> historian_limits;
};

class HistoryParts {
public:
    static Result<std::unique_ptr<HistoryParts>> open(HistoryPartsOptions options,
                                                      const std::vector<gateway::HistorySeriesName>& declared = {}) {
        auto parts = std::make_unique<HistoryParts>();
        gateway::HistoryOptions store_options = options;
        store_options.outbox = options.forward.has_value();
        auto store = gateway::HistoryStore::open(std::move(store_options), declared);
        if (!store) return store.error();
        parts->store = std::move(*store);
        gateway::HistoryReaderOptions reading;
        reading.database = options.database;
        reading.heartbeat = options.heartbeat;
        reading.thread = options.reader_thread;
        if (options.forward) {
            auto forwarder = gateway::HistoryForwarder::start(options.database, *options.forward, options.keep,
                                                              options.wall_clock, options.log);
            if (!forwarder) return forwarder.error();
            parts->forwarder_ = std::move(*forwarder);
            parts->store->on_outbox([forwarder = parts->forwarder_.get()](std::uint64_t rows, std::int64_t first_t) {
                forwarder->queued(rows, first_t);
            });
            reading.gateway = options.forward->gateway;
            gateway::HistorianAccess access;
            access.conninfo = options.forward->conninfo;
            access.password = options.forward->password;
            access.limits.connect_timeout_seconds =
                std::min(options.forward->connect_timeout_seconds, access.limits.connect_timeout_seconds);
            if (options.historian_limits) access.limits = *options.historian_limits;
            reading.historian = access;
        }
        auto reader = gateway::HistoryReader::open(std::move(reading), *parts->store, parts->forwarder_.get());
        if (!reader) return reader.error();
        parts->reader = std::move(*reader);
        return parts;
    }
    HistoryParts() = default;
    HistoryParts(const HistoryParts&) = delete;
    HistoryParts& operator=(const HistoryParts&) = delete;
    ~HistoryParts() {  // in the gateway's order: the reader, the store, the forwarder
        reader.reset();
        store.reset();
        forwarder_.reset();
    }

    void record(const gateway::ValueChange& change) { store->record(change); }
    Result<void> write_pending() { return store->write_pending(); }
    Result<void> enforce_retention() { return store->enforce_retention(); }
    std::uint64_t rows_written() const { return store->rows_written(); }
    std::uint64_t dropped() const { return store->dropped(); }
    Result<std::vector<gateway::HistorySeries>> query(const gateway::HistoryQuery& query) const { return reader->query(query); }
    Result<std::vector<std::string>> historian_gateways() const { return reader->historian_gateways(); }
    std::optional<gateway::ForwardStats> forward_stats() const { return reader->forward_stats(); }
    gateway::HistoryForwarder* forwarder() { return forwarder_.get(); }
    const std::filesystem::path& database() const { return store->database(); }

    std::unique_ptr<gateway::HistoryForwarder> forwarder_;
    std::unique_ptr<gateway::HistoryStore> store;
    std::unique_ptr<gateway::HistoryReader> reader;
};

}  // namespace loopwire::testing
