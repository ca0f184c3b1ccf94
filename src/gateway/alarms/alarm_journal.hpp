#pragma once
// The alarm journal: every transition of every alarm (gateway/alarms/alarm_engine.hpp) as a row
// of the `alarm_journal` table in the gateway's history file ([history] database), kept as long
// as the samples. Read back by GET /api/alarms/history and `loopwire alarms`, and at start, when
// each alarm takes up the state its last row says.
//
// Threads: append() only queues (the engine's loop never waits for SQLite); a writer thread
// (start()) commits what is queued every `commit_interval`, all of it in one transaction
// however many rows (a thousand alarms raised by one outage are one commit). Without the
// thread the owner calls write_pending() (tests, benches). The file's other writer, the history
// store, has its own connection; SQLite's lock puts the two commits one after the other.
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
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
    ~AlarmJournal();  // stops the writer, writes what is queued
    AlarmJournal(const AlarmJournal&) = delete;
    AlarmJournal& operator=(const AlarmJournal&) = delete;

    // Each alarm's state as its last row says (for AlarmEngine::restore).
    Result<std::map<std::string, RestoredState>> last_states();

    void append(const Transitions& transitions);
    Result<void> write_pending();  // without the writer thread
    void start(std::chrono::milliseconds commit_interval = std::chrono::milliseconds(250));

    std::uint64_t rows_written() const;
    std::uint64_t commits() const;  // transactions committed (a burst of rows is one)

private:
    AlarmJournal() = default;
    void run(std::stop_token stop, std::chrono::milliseconds interval);
    Result<void> commit(const Transitions& rows);

    std::chrono::seconds keep_{};
    std::function<void(const std::string&)> log_;
    sqlite::Connection db_;
    sqlite::Statement insert_;
    std::chrono::system_clock::time_point next_expiry_{};
    mutable std::mutex mutex_;
    std::condition_variable_any woken_;
    Transitions queue_;
    std::uint64_t written_ = 0;
    std::uint64_t commits_ = 0;
    bool failing_ = false;
    std::jthread thread_;  // last
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
