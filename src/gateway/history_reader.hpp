#pragma once
// The history as the HTTP API asks for it (gateway/history_source.hpp): this gateway's own
// series read from the store's SQLite file, another gateway's from the shared PostgreSQL
// historian, each on a connection of this reader's own.
//
// Threads: the asks given to run_blocking() wait in one queue for the reader's thread
// (lw-history-rd), which answers them in order; the store's writer (gateway/history_store.hpp)
// never answers one, so a month of history asked for, or a historian that takes its connect
// timeout (3 s) or its statement timeout (10 s) to answer, delays no commit: WAL lets the
// reader's connection (read-only) read while the writer commits. The HTTP API gives the whole
// ask, answer included, to run_blocking(); the answer goes back the way the asker said (an HTTP
// response posted to the engine's loop), so the loop never waits for the reader.
#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/result.hpp"
#include "gateway/historian_reader.hpp"
#include "gateway/history_source.hpp"
#include "gateway/sqlite_database.hpp"

namespace loopwire::gateway {

class HistoryStore;
class HistoryForwarder;

// Where another gateway's history is read: the historian this gateway forwards to.
struct HistorianAccess {
    std::string conninfo;
    std::optional<std::string> password;
    HistorianLimits limits;  // bounded for an asker that waits (an HTTP request)
};

struct HistoryReaderOptions {
    std::filesystem::path database;              // the store's file, already set up by the store
    std::chrono::milliseconds heartbeat{60000};  // the store's: a query looks back twice as far
    std::string gateway;                         // this gateway's name: gateway=it reads the file
    std::optional<HistorianAccess> historian;    // none: only this gateway's history is asked
    bool thread = true;  // false: run_blocking() runs the work at once, on the caller's thread (tests)
};

class HistoryReader final : public HistorySource {
public:
    // Opens its connection to the file (refused, saying so, when it is not a loopwire history);
    // the historian is connected to on the first ask for it. The figures GET /metrics shows come
    // from `store` and `forwarder` (none when not forwarding), which must outlive the reader.
    static Result<std::unique_ptr<HistoryReader>> open(HistoryReaderOptions options, const HistoryStore& store,
                                                       const HistoryForwarder* forwarder = nullptr);
    // Answers the asks still queued (each one's asker waits for it), then stops.
    ~HistoryReader() override;
    HistoryReader(const HistoryReader&) = delete;
    HistoryReader& operator=(const HistoryReader&) = delete;

    // Queues `work` for the reader's thread, in order; at once where it is given once the reader
    // stops (or when it has no thread).
    void run_blocking(std::function<void()> work) const override;
    // On the reader's thread when called there (from work given to run_blocking, as the HTTP
    // API does); from any other thread, handed to it and waited for.
    Result<std::vector<HistorySeries>> query(const HistoryQuery& query) const override;
    Result<std::vector<std::string>> historian_gateways() const override;
    Result<std::vector<AuditRecord>> audit(const AuditQuery& query) const override;
    std::uint64_t rows_written() const override;
    std::optional<ForwardStats> forward_stats() const override;

private:
    HistoryReader(HistoryReaderOptions options, const HistoryStore& store, const HistoryForwarder* forwarder);
    void run(std::stop_token stop);
    template <typename T>
    Result<T> on_reader_thread(std::function<Result<T>()> ask) const;
    Result<std::vector<HistorySeries>> read_file(const HistoryQuery& query) const;
    Result<std::vector<HistorySeries>> read_historian(const HistoryQuery& query) const;
    HistoryQuery with_look_back(HistoryQuery query) const;

    HistoryReaderOptions options_;
    const HistoryStore& store_;
    const HistoryForwarder* forwarder_;
    // Used on the reader's thread only (the caller's, without one): no lock of their own.
    mutable sqlite::Connection db_;
    std::unique_ptr<HistorianReader> historian_;
    // The queue of asks to the reader's thread, which blocks in SQLite and libpq.
    mutable std::mutex asks_mutex_;
    mutable std::condition_variable_any asks_woken_;
    mutable std::deque<std::function<void()>> asks_;
    bool threaded_ = false;  // asks go to the thread (asks lock)
    std::jthread thread_;            // last: stops and joins before the rest goes
};

}  // namespace loopwire::gateway
