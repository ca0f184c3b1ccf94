#pragma once
// A thin owner of SQLite connections and statements (libsqlite3): what the history store needs
// of it, with every failure turned into a Result whose message names the database file.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "common/result.hpp"

struct sqlite3;
struct sqlite3_stmt;

namespace loopwire::gateway::sqlite {

class Statement;

class Connection {
public:
    enum class Mode { read_write_create, read_only };

    // Opens `file`; the error names it. Nothing is read from it yet (SQLite reads lazily), so a
    // file that is not a database shows on the first statement.
    static Result<Connection> open(const std::string& file, Mode mode);

    Connection() = default;
    Connection(Connection&& other) noexcept = default;
    Connection& operator=(Connection&& other) noexcept = default;

    // Runs statements without results (or ignores them); the error names the file.
    Result<void> execute(std::string_view sql);
    Result<Statement> prepare(std::string_view sql);
    // The first column of the first row of `sql` as an integer or text (PRAGMAs).
    Result<std::int64_t> query_integer(std::string_view sql);
    Result<std::string> query_text(std::string_view sql);

    int changes() const;
    std::int64_t last_insert_id() const;
    const std::string& file() const { return file_; }
    Error failure(std::string_view doing) const;  // the connection's last error, named

private:
    struct Close {
        void operator()(sqlite3* db) const;
    };
    std::unique_ptr<sqlite3, Close> db_;
    std::string file_;
};

// A prepared statement: bind by 1-based index, step, read columns, reset for the next use.
class Statement {
public:
    Statement() = default;
    Statement(Statement&&) noexcept = default;
    Statement& operator=(Statement&&) noexcept = default;

    void bind(int index, std::int64_t value);
    void bind(int index, double value);
    void bind(int index, std::string_view value);  // copied by SQLite
    void bind_null(int index);
    void bind(int index, const std::optional<double>& value);
    void bind(int index, const std::optional<std::string>& value);

    // true: a row is ready; false: done; an error names the file.
    Result<bool> step();
    void reset();  // also clears the bindings

    std::int64_t integer(int column) const;
    double real(int column) const;
    bool is_null(int column) const;
    std::string text(int column) const;

private:
    friend class Connection;
    struct Finalize {
        void operator()(sqlite3_stmt* statement) const;
    };
    Statement(sqlite3_stmt* statement, std::string file) : statement_(statement), file_(std::move(file)) {}
    std::unique_ptr<sqlite3_stmt, Finalize> statement_;
    std::string file_;  // for messages
};

}  // namespace loopwire::gateway::sqlite
