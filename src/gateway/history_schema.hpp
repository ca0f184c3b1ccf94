#pragma once
// The history database's file: opening it, checking it is one (or creating it), WAL mode, and
// the tables (gateway/history_store.hpp describes them).
#include <filesystem>

#include "common/result.hpp"
#include "gateway/sqlite_database.hpp"

namespace loopwire::gateway::history {

// "PRAGMA application_id" of a loopwire history database ("LWHi"), so that another program's
// SQLite file given by mistake is refused rather than written into.
constexpr std::int64_t application_id = 0x4C574869;
constexpr std::int64_t schema_version = 1;

// The writer's connection: the file created if missing, in WAL mode, its tables created or
// checked. The error names the file and says what to do.
Result<sqlite::Connection> open_for_writing(const std::filesystem::path& file);
// A reader's connection to a database open_for_writing() prepared; a file that is not a loopwire
// history is refused, saying so. Read-only beside a running writer (its connection keeps the
// WAL's files); read-write by default, for a file no writer has open (its WAL is made again).
Result<sqlite::Connection> open_for_reading(const std::filesystem::path& file,
                                            sqlite::Connection::Mode mode = sqlite::Connection::Mode::read_write_create);
// For `--check`, without changing anything: an existing file must be a loopwire history (or an
// empty database), as open_for_writing() will want it; a missing one will be created.
Result<void> examine(const std::filesystem::path& file);

}  // namespace loopwire::gateway::history
