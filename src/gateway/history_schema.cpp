#include "gateway/history_schema.hpp"

#include <fmt/format.h>

#include "common/regular_file.hpp"

namespace loopwire::gateway::history {
namespace {

constexpr std::string_view create_tables = R"sql(
BEGIN IMMEDIATE;
CREATE TABLE series(
  id INTEGER PRIMARY KEY,
  device TEXT NOT NULL,
  parameter TEXT NOT NULL,
  unit TEXT NOT NULL,
  UNIQUE(device, parameter, unit));
-- value: the number (an enum's or bit field's raw word); NULL in a special state or with no
-- reply, when status says why. text: the label of an enum or bit field. status: NULL for "ok".
CREATE TABLE samples(
  series_id INTEGER NOT NULL,
  t INTEGER NOT NULL,
  value REAL,
  text TEXT,
  status TEXT,
  PRIMARY KEY(series_id, t)) WITHOUT ROWID;
-- minute: ms since the epoch / 60000; the samples with a value in it.
CREATE TABLE minutes(
  series_id INTEGER NOT NULL,
  minute INTEGER NOT NULL,
  lo REAL NOT NULL,
  hi REAL NOT NULL,
  total REAL NOT NULL,
  n INTEGER NOT NULL,
  PRIMARY KEY(series_id, minute)) WITHOUT ROWID;
PRAGMA application_id = 1280788585;
PRAGMA user_version = 1;
COMMIT;
)sql";
static_assert(application_id == 1280788585);

constexpr std::string_view create_gap_index =
    "CREATE INDEX IF NOT EXISTS samples_without_value ON samples(series_id, t) WHERE value IS NULL";

constexpr std::string_view create_outbox =
    "CREATE TABLE IF NOT EXISTS outbox(seq INTEGER PRIMARY KEY, series_id INTEGER NOT NULL, t INTEGER NOT NULL)";

// The historian's loopwire_values (postgres_history_schema.cpp) in the local file: one row a
// sample, its time as ISO 8601 UTC text (SQLite has no timestamp type) and `t` in ms beside it,
// device, parameter and unit by name, "ok" where the samples say NULL. The file is one gateway's,
// so it has no gateway column.
constexpr std::string_view create_values_view = R"sql(
CREATE VIEW IF NOT EXISTS loopwire_values AS
SELECT strftime('%Y-%m-%dT%H:%M:%fZ', s.t / 1000.0, 'unixepoch') AS time, s.t, n.device, n.parameter, n.unit, s.value,
       coalesce(s.status, 'ok') AS status, s.text
FROM samples s JOIN series n ON n.id = s.series_id
)sql";

// The audit of writes (gateway/write_audit.hpp): one row a write, from any front; t in ms since
// the epoch. Kept as long as the samples ([history] keep).
constexpr std::string_view create_writes =
    "CREATE TABLE IF NOT EXISTS writes(id INTEGER PRIMARY KEY, t INTEGER NOT NULL, front TEXT NOT NULL, peer TEXT NOT NULL, "
    "user TEXT NOT NULL, device TEXT NOT NULL, parameter TEXT NOT NULL, old_value TEXT NOT NULL, new_value TEXT NOT NULL, "
    "outcome TEXT NOT NULL)";
constexpr std::string_view create_writes_index = "CREATE INDEX IF NOT EXISTS writes_by_time ON writes(t)";

// Sparkplug's store and forward (gateway/sparkplug/sparkplug_pending.hpp): the data the node could
// not send while it was dead, one row a metric, until it is forwarded after the next births.
constexpr std::string_view create_sparkplug_pending =
    "CREATE TABLE IF NOT EXISTS sparkplug_pending(id INTEGER PRIMARY KEY, made_at INTEGER NOT NULL, "
    "device TEXT NOT NULL, metric TEXT NOT NULL, t INTEGER NOT NULL, quality INTEGER NOT NULL, "
    "kind INTEGER NOT NULL, value)";
constexpr std::string_view create_sparkplug_pending_index =
    "CREATE INDEX IF NOT EXISTS sparkplug_pending_by_time ON sparkplug_pending(made_at)";

Error refuse(const std::filesystem::path& file, const std::string& what) {
    return make_error(ErrorKind::usage, fmt::format("history database {}: {}", file.string(), what));
}

// What is wrong with the path itself, before SQLite is asked (its own message would only say
// "unable to open database file").
Result<void> check_path(const std::filesystem::path& file) {
    std::error_code error;
    if (std::filesystem::is_directory(file, error)) {
        return refuse(file, "is a folder; name a file in it, e.g. [history] database = \"plant.db\"");
    }
    const auto folder = file.parent_path().empty() ? std::filesystem::path(".") : file.parent_path();
    if (!std::filesystem::is_directory(folder, error)) {
        return refuse(file, fmt::format("the folder {} does not exist; create it or name another file in [history] database",
                                        folder.string()));
    }
    return {};
}

// Whether the file is a loopwire history database already (true), an empty one to set up
// (false), or something else (the error).
Result<bool> recognise(sqlite::Connection& db, const std::filesystem::path& file) {
    auto id = db.query_integer("PRAGMA application_id");
    if (!id) {
        return refuse(file, fmt::format("cannot be read as an SQLite database ({}); if it is not the history, name another "
                                        "file in [history] database, else move the damaged file away and start a new one",
                                        id.error().message));
    }
    if (*id == application_id) {
        auto version = db.query_integer("PRAGMA user_version");
        if (!version) return version.error();
        if (*version != schema_version) {
            return refuse(file, fmt::format("was written by another version of loopwire (schema {}, this one reads {}); "
                                            "name another file in [history] database", *version, schema_version));
        }
        return true;
    }
    auto tables = db.query_integer("SELECT count(*) FROM sqlite_schema");
    if (!tables) return tables.error();
    if (*id != 0 || *tables != 0) {
        return refuse(file, "is an SQLite database of another program, not a loopwire history; name another file in "
                            "[history] database");
    }
    return false;
}

}  // namespace

Result<sqlite::Connection> open_for_writing(const std::filesystem::path& file) {
    if (auto path = check_path(file); !path) return path.error();
    auto db = sqlite::Connection::open(file.string(), sqlite::Connection::Mode::read_write_create);
    if (!db) return refuse(file, fmt::format("cannot be opened ({}); check the gateway may write to its folder", db.error().message));
    auto known = recognise(*db, file);
    if (!known) return known.error();
    // WAL: a crash leaves every committed transaction whole, and readers (the HTTP API) never
    // wait for the writer. It needs the -wal and -shm files beside the database.
    auto mode = db->query_text("PRAGMA journal_mode = WAL");
    if (!mode || *mode != "wal") {
        return refuse(file, fmt::format("cannot be switched to WAL mode ({}); the gateway needs to write the file and create "
                                        "its -wal and -shm files in its folder",
                                        mode ? "journal mode " + *mode : mode.error().message));
    }
    // NORMAL in WAL mode: a process crash loses nothing committed (the WAL is in the OS's
    // cache); only a power cut may lose the last commits, never the file's consistency.
    if (auto synchronous = db->execute("PRAGMA synchronous = NORMAL"); !synchronous) return synchronous.error();
    if (!*known) {
        if (auto created = db->execute(create_tables); !created) {
            (void)db->execute("ROLLBACK");
            return refuse(file, fmt::format("cannot be written ({}); check the gateway may write to it and its folder",
                                            created.error().message));
        }
    }
    // The rows without a value (no reply, a special state, stale) are few: indexed apart, the
    // gaps of a month of history are found without reading its samples (history_query.cpp).
    // Created here rather than with the tables so that a file of an earlier loopwire gets it too.
    if (auto indexed = db->execute(create_gap_index); !indexed) {
        return refuse(file, fmt::format("cannot be indexed ({}); check the gateway may write to it and its folder",
                                        indexed.error().message));
    }
    // The rows waiting to be forwarded to PostgreSQL (gateway/history_forwarder.hpp), in the
    // order they were committed, and the view for Grafana's SQLite data source and the sqlite3
    // shell. Created in every file, as the index above, so a file of an earlier loopwire, or
    // one that starts being forwarded later, needs no other schema; the outbox stays empty
    // unless [history] forward_to. The audit's table, the same way: a file of an earlier
    // loopwire gains it, and is still the schema it was (only added to, nothing changed).
    for (const std::string_view sql : {create_outbox, create_values_view, create_writes, create_writes_index,
                                       create_sparkplug_pending, create_sparkplug_pending_index}) {
        if (auto made = db->execute(sql); !made) {
            return refuse(file, fmt::format("cannot be written ({}); check the gateway may write to it and its folder",
                                            made.error().message));
        }
    }
    return db;
}

Result<sqlite::Connection> open_for_reading(const std::filesystem::path& file, sqlite::Connection::Mode mode) {
    auto db = sqlite::Connection::open(file.string(), mode);
    if (!db) return db.error();
    // A file that is not a history said so, not a failed query ("no such table: series").
    auto known = recognise(*db, file);
    if (!known) return known.error();
    if (!*known) return refuse(file, "is an empty SQLite database, not a loopwire history; name the file of a gateway's [history]");
    return db;
}

Result<void> examine(const std::filesystem::path& file) {
    std::error_code error;
    if (!std::filesystem::exists(file, error)) return {};  // created when the gateway starts
    if (auto path = check_path(file); !path) return path.error();
    if (auto what = not_a_regular_file(file)) return refuse(file, *what);
    auto db = sqlite::Connection::open(file.string(), sqlite::Connection::Mode::read_only);
    if (!db) return refuse(file, fmt::format("cannot be opened ({})", db.error().message));
    auto known = recognise(*db, file);
    if (!known) return known.error();
    return {};
}

}  // namespace loopwire::gateway::history
