#pragma once
// Other gateways' history, read from the shared PostgreSQL historian for
// /api/history?gateway=NAME (and the dashboard's list of gateways), on the history reader's
// thread (gateway/history_reader.hpp), never the writer's that commits this gateway's history.
//
// One connection, kept between requests (a connect costs more than most queries) and opened
// again when a request finds it broken (that request is then asked once more on the new one). The requests take turns on it, and each is bounded so
// that a slow or absent database cannot hold an HTTP worker for long: a connect by
// connect_timeout, a statement by the session's statement_timeout, and the wait for the turn
// by both together; past a bound the request fails with ErrorKind::timeout, a database that
// cannot be reached with ErrorKind::link (the API answers 503 to both). A host that stops
// answering in the middle of a statement without closing its socket still holds its request
// until the kernel gives up on the connection.
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "gateway/history_source.hpp"
#include "gateway/postgres_database.hpp"

namespace loopwire::gateway {

struct HistorianLimits {
    int connect_timeout_seconds = 3;
    std::chrono::milliseconds statement_timeout{10000};
};

class HistorianReader {
public:
    HistorianReader(std::string conninfo, std::optional<std::string> password, HistorianLimits limits = {});

    Result<std::vector<HistorySeries>> query(const std::string& gateway, const HistoryQuery& query);
    // The names of the gateways that have forwarded any history, sorted.
    Result<std::vector<std::string>> gateways();

    // What the connection's sessions are called on the server (pg_stat_activity), to tell it apart.
    static constexpr const char* application_name = "loopwire-history-reader";

private:
    template <typename T, typename Ask>
    Result<T> with_connection(Ask ask);
    Result<void> connect();

    std::string conninfo_;
    std::optional<std::string> password_;
    HistorianLimits limits_;
    // One request at a time on the connection, waited for within a bound. A flag under a plain
    // mutex and a condition variable, not std::timed_mutex: ThreadSanitizer (GCC 12's) does not
    // see the clock lock a timed_mutex takes, and reports its unlock as one of an unlocked mutex.
    class Turn;
    std::mutex mutex_;
    std::condition_variable turn_ended_;
    bool busy_ = false;  // under mutex_
    std::optional<postgres::Connection> db_;
};

}  // namespace loopwire::gateway
