#pragma once
// The local file's side of forwarding the history (gateway/history_forwarder.hpp): the outbox
// rows the store's writer noted (history_store.cpp), read in order with their samples, and
// cleared once the historian has committed them. On a connection of its own to the file, used by
// the forwarder's thread alone.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "gateway/sqlite_database.hpp"

namespace loopwire::gateway {

struct OutboxRow {
    std::int64_t series = 0;  // the local file's series id
    std::int64_t t = 0;       // ms since the epoch
    std::optional<double> value;
    std::optional<std::string> text;
    std::optional<std::string> status;
};

struct OutboxBatch {
    std::int64_t last_seq = 0;  // the outbox's sequence number of the last row read; 0: none
    std::uint64_t expired = 0;  // outbox rows whose sample retention already deleted
    std::vector<OutboxRow> rows;
    bool empty() const { return last_seq == 0; }
};

struct SeriesNames {
    std::string device;
    std::string parameter;
    std::string unit;
};

class Outbox {
public:
    static Result<Outbox> open(const std::filesystem::path& database);

    // Up to `limit` rows after sequence number `after`, in order.
    Result<OutboxBatch> read(std::int64_t after, std::size_t limit);
    // Deletes the rows up to sequence number `last` (inclusive): the historian has them.
    Result<void> clear(std::int64_t last);
    Result<SeriesNames> names(std::int64_t series);
    Result<std::int64_t> waiting();
    Result<std::int64_t> oldest_t();  // 0 when empty
    const std::string& file() const { return db_.file(); }

private:
    sqlite::Connection db_;
};

}  // namespace loopwire::gateway
