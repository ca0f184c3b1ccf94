#include "gateway/postgres_database.hpp"

#include <libpq-fe.h>

#include <algorithm>
#include <charconv>

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
                                       int connect_timeout_seconds, const char* application_name) {
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
    result.connection_.reset(PQconnectdbParams(keys.data(), values.data(), 1));
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
