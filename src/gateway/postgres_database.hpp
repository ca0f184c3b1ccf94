#pragma once
// A thin owner of PostgreSQL connections and results (libpq, the C API): what the history's
// forwarder needs of it, with every failure turned into a Result that says what went wrong and,
// for the failures a user can fix (a wrong password, a missing database), what to do.
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/result.hpp"

struct pg_conn;
struct pg_result;

namespace loopwire::gateway::postgres {

// A statement's result: rows of text (the forwarder only asks for a few small answers).
class QueryResult {
public:
    int rows() const;
    bool is_null(int row, int column) const;
    std::string text(int row, int column) const;
    long long integer(int row, int column) const;  // a text column parsed as an integer

private:
    friend class Connection;
    struct Clear {
        void operator()(pg_result* result) const;
    };
    explicit QueryResult(pg_result* result) : result_(result) {}
    std::unique_ptr<pg_result, Clear> result_;
};

// Text parameters ($1, $2, ...), NULL where empty: the values the server parses by their type.
using Parameters = std::vector<std::optional<std::string>>;

// Who is told of a call to the server (the connect, a statement) that does not come back: a
// server frozen (stopped, or its host gone without a word) holds a call for as long as TCP keeps
// the connection, minutes or for ever, and nothing would say so. `log` is given a warning line
// (beginning "warning: ") once a call has waited `after`, again every minute it goes on waiting,
// and a line when it comes back, with how long it took. No log: not watched.
struct StallWatch {
    std::function<void(const std::string&)> log;
    std::chrono::milliseconds after{10000};
};

class Connection {
public:
    // Connects with `conninfo` (a postgresql:// URL or key=value pairs, libpq's own forms) and
    // an optional password that overrides any in it (PGPASSFILE works as libpq defines it).
    // The error names the server without the password and says what to do.
    // `application_name` is what the server's pg_stat_activity calls the session.
    // `watch`: who is told of a connect or statement that does not come back.
    static Result<Connection> connect(const std::string& conninfo, const std::optional<std::string>& password,
                                      int connect_timeout_seconds, const char* application_name = "loopwire",
                                      StallWatch watch = {});

    Connection() = default;
    Connection(Connection&&) noexcept = default;
    Connection& operator=(Connection&&) noexcept = default;

    Result<QueryResult> execute(std::string_view sql, const Parameters& parameters = {});
    Result<void> run(std::string_view sql, const Parameters& parameters = {});  // the rows, if any, unread
    // Runs `copy` (a COPY ... FROM STDIN) and sends `data` in the format it names: the cheapest
    // way into the server for many rows (no per-row statement, no array to parse).
    Result<void> copy_in(std::string_view copy, std::string_view data);
    // copy_in in two halves: copy_send returns once the rows are sent, while the server may still
    // be taking them, so the caller can do other work (read its next rows) before copy_finish
    // waits for the outcome. Nothing else may be sent on the connection in between.
    Result<void> copy_send(std::string_view copy, std::string_view data);
    Result<void> copy_finish();
    bool broken() const;  // the connection is gone: reconnect rather than retry on it
    // The SQLSTATE of the last statement that failed ("23505": a unique key already there).
    const std::string& failed_state() const { return failed_state_; }
    const std::string& server() const { return server_; }

private:
    Error failure(const pg_result* result);  // the statement's error, with its remedy; notes its SQLSTATE
    struct Finish {
        void operator()(pg_conn* connection) const;
    };
    std::unique_ptr<pg_conn, Finish> connection_;
    std::string server_;  // for messages: user@host:port/database
    std::string failed_state_;
    StallWatch watch_;
};

// A PostgreSQL text array literal of the values ("{1,2,NULL}"), quoted so that any text fits:
// a whole batch travels as one parameter per column (unnest() on the server side).
std::string array_literal(const std::vector<std::optional<std::string>>& values);

// Whether libpq can read the connection string; the error is libpq's, without the text itself
// (it may hold a password).
Result<void> check_conninfo(const std::string& conninfo);

// Whether the text names a PostgreSQL server rather than a file (the URL forms and key=value).
bool is_conninfo(std::string_view text);

}  // namespace loopwire::gateway::postgres
