#include "gateway/postgres_database.hpp"

#include <libpq-fe.h>

#include <algorithm>
#include <charconv>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include <fmt/format.h>

namespace loopwire::gateway::postgres {
namespace {

std::string trimmed(std::string text) {
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    return text;
}

// What the user can do about the failures libpq reports in words: its message stays as it is,
// with the remedy after it.
std::string remedy(std::string_view message) {
    if (message.find("password authentication failed") != std::string_view::npos ||
        message.find("no password supplied") != std::string_view::npos) {
        return "check [history] password_file (or PGPASSFILE) holds this user's password";
    }
    if (message.find("does not exist") != std::string_view::npos && message.find("database") != std::string_view::npos) {
        return "create the database (createdb) or name an existing one in [history] forward_to";
    }
    if (message.find("role") != std::string_view::npos && message.find("does not exist") != std::string_view::npos) {
        return "create the user on the server or name another in [history] forward_to";
    }
    if (message.find("permission denied") != std::string_view::npos) {
        return "let the user create tables (GRANT CREATE ON SCHEMA public TO the user) or have the database's owner "
               "run `loopwire gateway --check` once to create them";
    }
    if (message.find("Connection refused") != std::string_view::npos ||
        message.find("No such file or directory") != std::string_view::npos ||
        message.find("timeout expired") != std::string_view::npos) {
        return "check the server runs and [history] forward_to names its host and port (or socket folder)";
    }
    return {};
}

std::string described(pg_conn* connection) {
    if (!connection) return "(unknown server)";
    const char* host = PQhost(connection);
    std::string where = (host && *host == '/') ? fmt::format("socket {}/.s.PGSQL.{}", host, PQport(connection))
                                               : fmt::format("{}:{}", host ? host : "", PQport(connection));
    return fmt::format("postgresql {}@{}/{}", PQuser(connection), where, PQdb(connection));
}

std::string seconds_text(std::chrono::steady_clock::duration waited) {
    const double seconds = std::chrono::duration<double>(waited).count();
    return seconds < 10 ? fmt::format("{:.1f} s", seconds) : fmt::format("{:.0f} s", seconds);
}

// The calls under way that are watched (StallWatch), and one thread that tells of those that
// have waited too long. Process-wide and never destroyed: a call may end on any thread at any
// time, also while the process exits.
class StallWatcher {
public:
    static StallWatcher& instance() {
        static auto* watcher = new StallWatcher;
        return *watcher;
    }

    std::uint64_t begin(const StallWatch& watch, const std::string& server, const char* what) {
        const auto now = std::chrono::steady_clock::now();
        std::lock_guard lock(mutex_);
        if (!thread_started_) {
            std::thread([this] { run(); }).detach();
            thread_started_ = true;
        }
        const std::uint64_t id = ++last_id_;
        calls_[id] = Call{watch, server.empty() ? "the historian" : server, what, now, now + watch.after, false};
        changed_.notify_one();
        return id;
    }

    void end(std::uint64_t id) {
        Call call;
        {
            std::lock_guard lock(mutex_);
            auto it = calls_.find(id);
            if (it == calls_.end()) return;
            call = std::move(it->second);
            calls_.erase(it);
        }
        if (!call.reported) return;
        call.watch.log(fmt::format("notice: {} answers again: {} came back after {}", call.server, call.what,
                                   seconds_text(std::chrono::steady_clock::now() - call.started)));
    }

private:
    struct Call {
        StallWatch watch;
        std::string server;
        const char* what = "";
        std::chrono::steady_clock::time_point started;
        std::chrono::steady_clock::time_point next_report;
        bool reported = false;
    };
    static constexpr std::chrono::minutes report_again{1};

    void run() {
        std::unique_lock lock(mutex_);
        for (;;) {
            if (calls_.empty()) {
                changed_.wait(lock);
                continue;
            }
            auto earliest = calls_.begin()->second.next_report;
            for (const auto& [id, call] : calls_) earliest = std::min(earliest, call.next_report);
            if (changed_.wait_until(lock, earliest) == std::cv_status::no_timeout) continue;
            const auto now = std::chrono::steady_clock::now();
            std::vector<std::pair<std::function<void(const std::string&)>, std::string>> lines;
            for (auto& [id, call] : calls_) {
                if (call.next_report > now) continue;
                lines.emplace_back(call.watch.log,
                                   fmt::format("warning: {} has not answered for {}: {} waits (the server stopped, or "
                                               "the network to it gone?); {}",
                                               call.server, seconds_text(now - call.started), call.what,
                                               call.reported ? "still waiting" : "waiting on, and saying so when it answers"));
                call.reported = true;
                call.next_report = now + report_again;
            }
            lock.unlock();
            for (const auto& [log, line] : lines) log(line);
            lock.lock();
        }
    }

    std::mutex mutex_;
    std::condition_variable changed_;
    std::map<std::uint64_t, Call> calls_;
    std::uint64_t last_id_ = 0;
    bool thread_started_ = false;
};

// One call to the server, watched while it lasts.
class Watched {
public:
    Watched(const StallWatch& watch, const std::string& server, const char* what)
        : id_(watch.log ? StallWatcher::instance().begin(watch, server, what) : 0) {}
    ~Watched() {
        if (id_ != 0) StallWatcher::instance().end(id_);
    }
    Watched(const Watched&) = delete;
    Watched& operator=(const Watched&) = delete;

private:
    std::uint64_t id_;
};

}  // namespace

void QueryResult::Clear::operator()(pg_result* result) const { PQclear(result); }
void Connection::Finish::operator()(pg_conn* connection) const { PQfinish(connection); }

int QueryResult::rows() const { return PQntuples(result_.get()); }
bool QueryResult::is_null(int row, int column) const { return PQgetisnull(result_.get(), row, column) != 0; }
std::string QueryResult::text(int row, int column) const { return PQgetvalue(result_.get(), row, column); }

long long QueryResult::integer(int row, int column) const {
    const std::string value = text(row, column);
    long long parsed = 0;
    std::from_chars(value.data(), value.data() + value.size(), parsed);
    return parsed;
}

Result<Connection> Connection::connect(const std::string& conninfo, const std::optional<std::string>& password,
                                       int connect_timeout_seconds, const char* application_name, StallWatch watch) {
    // expand_dbname: the "dbname" value is the whole connection string; the keywords after it
    // override what it says (the password from password_file, a bound on the connect).
    const std::string timeout = std::to_string(connect_timeout_seconds);
    std::vector<const char*> keys{"dbname", "connect_timeout", "application_name"};
    std::vector<const char*> values{conninfo.c_str(), timeout.c_str(), application_name};
    if (password) {
        keys.push_back("password");
        values.push_back(password->c_str());
    }
    keys.push_back(nullptr);
    values.push_back(nullptr);
    Connection result;
    {
        const Watched watched(watch, {}, "the connect");
        result.connection_.reset(PQconnectdbParams(keys.data(), values.data(), 1));
    }
    result.watch_ = std::move(watch);
    if (!result.connection_) return make_error(ErrorKind::link, "postgresql: out of memory");
    result.server_ = described(result.connection_.get());
    // The server's notices ("relation ... already exists, skipping") are not the gateway's to
    // print: libpq would write them to stderr.
    PQsetNoticeProcessor(result.connection_.get(), [](void*, const char*) {}, nullptr);
    if (PQstatus(result.connection_.get()) != CONNECTION_OK) {
        const std::string message = trimmed(PQerrorMessage(result.connection_.get()));
        const std::string what = remedy(message);
        return make_error(ErrorKind::link, fmt::format("{}: cannot connect: {}{}", result.server_, message,
                                                       what.empty() ? "" : "; " + what));
    }
    return result;
}

bool Connection::broken() const { return !connection_ || PQstatus(connection_.get()) != CONNECTION_OK; }

Result<QueryResult> Connection::execute(std::string_view sql, const Parameters& parameters) {
    const std::string text(sql);
    std::vector<const char*> values;
    values.reserve(parameters.size());
    for (const auto& parameter : parameters) values.push_back(parameter ? parameter->c_str() : nullptr);
    const Watched watched(watch_, server_, "a statement");
    // Without parameters, PQexec: it takes several statements in one text (the schema's).
    QueryResult result(values.empty() ? PQexec(connection_.get(), text.c_str())
                                      : PQexecParams(connection_.get(), text.c_str(), static_cast<int>(values.size()),
                                                     nullptr, values.data(), nullptr, nullptr, 0));
    const ExecStatusType status = result.result_ ? PQresultStatus(result.result_.get()) : PGRES_FATAL_ERROR;
    if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK) return failure(result.result_.get());
    return result;
}

Error Connection::failure(const pg_result* result) {
    const char* state = result ? PQresultErrorField(result, PG_DIAG_SQLSTATE) : nullptr;
    failed_state_ = state ? state : "";
    const std::string message = trimmed(PQerrorMessage(connection_.get()));
    const std::string what = remedy(message);
    return make_error(ErrorKind::link, fmt::format("{}: {}{}", server_, message, what.empty() ? "" : "; " + what));
}

Result<void> Connection::copy_in(std::string_view copy, std::string_view data) {
    if (auto sent = copy_send(copy, data); !sent) return sent;
    return copy_finish();
}

Result<void> Connection::copy_send(std::string_view copy, std::string_view data) {
    const std::string text(copy);
    const Watched watched(watch_, server_, "sending rows");
    QueryResult started(PQexec(connection_.get(), text.c_str()));
    if (!started.result_ || PQresultStatus(started.result_.get()) != PGRES_COPY_IN) return failure(started.result_.get());
    // In pieces: PQputCopyData takes an int length, and a batch may one day be larger.
    constexpr std::size_t piece = 1 << 20;
    bool sent = true;
    for (std::size_t at = 0; sent && at < data.size(); at += piece) {
        const std::size_t size = std::min(piece, data.size() - at);
        sent = PQputCopyData(connection_.get(), data.data() + at, static_cast<int>(size)) == 1;
    }
    // A failed send still ends the COPY (with an error), so the connection leaves COPY mode.
    if (PQputCopyEnd(connection_.get(), sent ? nullptr : "loopwire: sending the rows failed") != 1) return failure(nullptr);
    if (!sent) return copy_finish();  // the server's word on the COPY it was told to abandon
    return {};
}

Result<void> Connection::copy_finish() {
    const Watched watched(watch_, server_, "the end of sending rows");
    QueryResult ended(PQgetResult(connection_.get()));
    const bool done = ended.result_ && PQresultStatus(ended.result_.get()) == PGRES_COMMAND_OK;
    Result<void> outcome;
    if (!done) outcome = failure(ended.result_.get());
    // The results are read to the end (a null one) before the next statement can be sent.
    while (pg_result* rest = PQgetResult(connection_.get())) PQclear(rest);
    return outcome;
}

Result<void> Connection::run(std::string_view sql, const Parameters& parameters) {
    auto done = execute(sql, parameters);
    if (!done) return done.error();
    return {};
}

std::string array_literal(const std::vector<std::optional<std::string>>& values) {
    std::string literal = "{";
    for (std::size_t i = 0; i < values.size(); ++i) {
        if (i != 0) literal += ',';
        if (!values[i]) {
            literal += "NULL";
            continue;
        }
        literal += '"';
        for (char c : *values[i]) {
            if (c == '"' || c == '\\') literal += '\\';
            literal += c;
        }
        literal += '"';
    }
    literal += '}';
    return literal;
}

Result<void> check_conninfo(const std::string& conninfo) {
    char* message = nullptr;
    PQconninfoOption* options = PQconninfoParse(conninfo.c_str(), &message);
    if (options) {
        PQconninfoFree(options);
        return {};
    }
    std::string text = message ? trimmed(message) : "out of memory";
    PQfreemem(message);
    return make_error(ErrorKind::usage, fmt::format("libpq cannot read it: {}", text));
}

bool is_conninfo(std::string_view text) {
    return text.starts_with("postgresql://") || text.starts_with("postgres://") || text.find('=') != std::string_view::npos;
}

}  // namespace loopwire::gateway::postgres
