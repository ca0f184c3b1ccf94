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

// A row of the file's audit table (`writes`), as the historian's loopwire_writes takes it; its
// place in the table's order is (t, id).
struct LocalWrite {
    std::int64_t id = 0;
    std::int64_t t = 0;
    std::vector<std::string> fields;  // front, peer, user, device, parameter, old_value, new_value, outcome
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
    // Up to `limit` audit rows after (t, id), in that order: the rows the historian does not have
    // yet when (t, id) is the last one it has.
    Result<std::vector<LocalWrite>> writes_after(std::int64_t t, std::int64_t id, std::size_t limit);
    Result<std::int64_t> waiting();
    Result<std::int64_t> oldest_t();  // 0 when empty
    const std::string& file() const { return db_.file(); }

private:
    sqlite::Connection db_;
};

}  // namespace loopwire::gateway
