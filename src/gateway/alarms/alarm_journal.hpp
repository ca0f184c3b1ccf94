#pragma once
// The alarm journal: every transition of every alarm (gateway/alarms/alarm_engine.hpp) as a row
// of the `alarm_journal` table in the gateway's history file ([history] database), kept as long
// as the samples. Read back by GET /api/alarms/history and `loopwire alarms`, and at start, when
// each alarm takes up the state its last row says.
//
// Threads: append() only queues (the engine's loop never waits for SQLite); write_pending()
// commits what is queued, all of it in one transaction however many rows (a thousand alarms
// raised by one outage are one commit). The gateway has the history store's writer thread call
// it after each of its own commits (HistoryStore::also_write): no thread of its own, and on its
// own connection, so the two commits of the file are one after the other.
#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "gateway/alarms/alarm_engine.hpp"
#include "gateway/sqlite_database.hpp"

namespace loopwire::gateway::alarms {

class AlarmJournal final {
public:
    // Opens (or creates) the history file and the journal's table in it.
    static Result<std::unique_ptr<AlarmJournal>> open(const std::filesystem::path& database,
                                                      std::chrono::seconds keep = std::chrono::hours(24 * 90),
                                                      std::function<void(const std::string&)> log = {});
    ~AlarmJournal();  // writes what is queued
    AlarmJournal(const AlarmJournal&) = delete;
    AlarmJournal& operator=(const AlarmJournal&) = delete;

    // Each alarm's state as its last row said when the journal opened (for AlarmEngine::restore).
    const std::map<std::string, RestoredState>& last_states() const { return restored_; }

    void append(const Transitions& transitions);
    Result<void> write_pending();  // never beside itself: the history writer's thread, or the owner's

    std::uint64_t rows_written() const;
    std::uint64_t commits() const;  // transactions committed (a burst of rows is one)

private:
    AlarmJournal() = default;
    Result<void> commit(const Transitions& rows);
    Result<std::map<std::string, RestoredState>> read_last_states();

    std::chrono::seconds keep_{};
    std::function<void(const std::string&)> log_;
    sqlite::Connection db_;
    sqlite::Statement insert_;
    std::map<std::string, RestoredState> restored_;
    std::chrono::system_clock::time_point next_expiry_{};
    mutable std::mutex mutex_;
    Transitions queue_;
    std::uint64_t written_ = 0;
    std::uint64_t commits_ = 0;
    bool failing_ = false;
};

// One journal row as read back.
struct JournalRow {
    std::chrono::system_clock::time_point time;
    std::string id;
    std::string device;
    std::string parameter;
    std::string state;
    std::optional<double> value;
    std::string unit;
    std::string severity;
    std::string message;
    std::string user;
    std::string comment;
};

// The rows stamped in [from, to], newest first, at most `limit`; from a connection to the
// history file opened for reading (gateway/history_schema.hpp).
Result<std::vector<JournalRow>> read_journal(sqlite::Connection& db, std::chrono::system_clock::time_point from,
                                             std::chrono::system_clock::time_point to, std::size_t limit);

std::string journal_json(const std::vector<JournalRow>& rows);
std::string journal_csv(const std::vector<JournalRow>& rows);

}  // namespace loopwire::gateway::alarms
