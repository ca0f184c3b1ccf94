#include "gateway/sqlite_database.hpp"

#include <sqlite3.h>

#include <fmt/format.h>

namespace loopwire::gateway::sqlite {
namespace {

Error named_error(const std::string& file, std::string_view doing, sqlite3* db, int code) {
    const char* message = db ? sqlite3_errmsg(db) : sqlite3_errstr(code);
    return make_error(ErrorKind::link, fmt::format("{}: {} failed: {}", file, doing, message));
}

}  // namespace

void Connection::Close::operator()(sqlite3* db) const { sqlite3_close_v2(db); }
void Statement::Finalize::operator()(sqlite3_stmt* statement) const { sqlite3_finalize(statement); }

Result<Connection> Connection::open(const std::string& file, Mode mode) {
    // NOMUTEX: each connection is used by one thread at a time (the store's locks see to it).
    const int flags = (mode == Mode::read_only ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE) |
                      SQLITE_OPEN_NOMUTEX;
    sqlite3* db = nullptr;
    const int code = sqlite3_open_v2(file.c_str(), &db, flags, nullptr);
    Connection connection;
    connection.db_.reset(db);
    connection.file_ = file;
    if (code != SQLITE_OK) return named_error(file, "opening the database", db, code);
    sqlite3_extended_result_codes(db, 1);
    // Another process (a backup, the sqlite3 shell) may hold the lock for a moment: wait for it
    // rather than fail at once.
    sqlite3_busy_timeout(db, 2000);
    return connection;
}

Error Connection::failure(std::string_view doing) const { return named_error(file_, doing, db_.get(), SQLITE_ERROR); }

Result<void> Connection::execute(std::string_view sql) {
    char* message = nullptr;
    const std::string text(sql);
    const int code = sqlite3_exec(db_.get(), text.c_str(), nullptr, nullptr, &message);
    if (code != SQLITE_OK) {
        std::string why = message ? message : sqlite3_errstr(code);
        sqlite3_free(message);
        return make_error(ErrorKind::link, fmt::format("{}: {} failed: {}", file_, text, why));
    }
    return {};
}

Result<Statement> Connection::prepare(std::string_view sql) {
    sqlite3_stmt* statement = nullptr;
    const int code = sqlite3_prepare_v3(db_.get(), sql.data(), static_cast<int>(sql.size()), SQLITE_PREPARE_PERSISTENT,
                                        &statement, nullptr);
    if (code != SQLITE_OK) return named_error(file_, fmt::format("preparing \"{}\"", sql), db_.get(), code);
    return Statement(statement, file_);
}

Result<std::int64_t> Connection::query_integer(std::string_view sql) {
    auto statement = prepare(sql);
    if (!statement) return statement.error();
    auto row = statement->step();
    if (!row) return row.error();
    if (!*row) return make_error(ErrorKind::link, fmt::format("{}: {} gave no row", file_, sql));
    return statement->integer(0);
}

Result<std::string> Connection::query_text(std::string_view sql) {
    auto statement = prepare(sql);
    if (!statement) return statement.error();
    auto row = statement->step();
    if (!row) return row.error();
    if (!*row) return make_error(ErrorKind::link, fmt::format("{}: {} gave no row", file_, sql));
    return statement->text(0);
}

int Connection::changes() const { return sqlite3_changes(db_.get()); }
std::int64_t Connection::last_insert_id() const { return sqlite3_last_insert_rowid(db_.get()); }

void Statement::bind(int index, std::int64_t value) { sqlite3_bind_int64(statement_.get(), index, value); }
void Statement::bind(int index, double value) { sqlite3_bind_double(statement_.get(), index, value); }
void Statement::bind(int index, std::string_view value) {
    sqlite3_bind_text64(statement_.get(), index, value.data(), value.size(), SQLITE_TRANSIENT, SQLITE_UTF8);
}
void Statement::bind_null(int index) { sqlite3_bind_null(statement_.get(), index); }
void Statement::bind(int index, const std::optional<double>& value) {
    if (value) bind(index, *value);
    else bind_null(index);
}
void Statement::bind(int index, const std::optional<std::string>& value) {
    if (value) bind(index, std::string_view(*value));
    else bind_null(index);
}

Result<bool> Statement::step() {
    const int code = sqlite3_step(statement_.get());
    if (code == SQLITE_ROW) return true;
    if (code == SQLITE_DONE) return false;
    sqlite3* db = sqlite3_db_handle(statement_.get());
    Error error = named_error(file_, fmt::format("\"{}\"", sqlite3_sql(statement_.get())), db, code);
    sqlite3_reset(statement_.get());
    return error;
}

void Statement::reset() {
    sqlite3_reset(statement_.get());
    sqlite3_clear_bindings(statement_.get());
}

std::int64_t Statement::integer(int column) const { return sqlite3_column_int64(statement_.get(), column); }
double Statement::real(int column) const { return sqlite3_column_double(statement_.get(), column); }
bool Statement::is_null(int column) const { return sqlite3_column_type(statement_.get(), column) == SQLITE_NULL; }
std::string Statement::text(int column) const {
    const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(statement_.get(), column));
    return text ? std::string(text, static_cast<std::size_t>(sqlite3_column_bytes(statement_.get(), column))) : std::string();
}

}  // namespace loopwire::gateway::sqlite
