#include "gateway/alarms/alarm_journal.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "gateway/history_schema.hpp"
#include "gateway/http_text.hpp"

namespace loopwire::gateway::alarms {
namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::system_clock;

std::int64_t to_ms(Clock::time_point time) { return std::chrono::duration_cast<milliseconds>(time.time_since_epoch()).count(); }
Clock::time_point from_ms(std::int64_t ms) { return Clock::time_point(milliseconds(ms)); }

// Added to any history file, as the audit's `writes` table is: a file of an earlier loopwire
// gains it and is otherwise unchanged. t and shelved_until in ms since the epoch.
constexpr std::string_view create_journal =
    "CREATE TABLE IF NOT EXISTS alarm_journal(id INTEGER PRIMARY KEY, t INTEGER NOT NULL, alarm TEXT NOT NULL, "
    "device TEXT NOT NULL, parameter TEXT NOT NULL, state TEXT NOT NULL, value REAL, unit TEXT NOT NULL, "
    "severity TEXT NOT NULL, message TEXT NOT NULL, user TEXT NOT NULL, comment TEXT NOT NULL, shelved_until INTEGER)";
constexpr std::string_view create_by_time = "CREATE INDEX IF NOT EXISTS alarm_journal_by_time ON alarm_journal(t)";
constexpr std::string_view create_by_alarm = "CREATE INDEX IF NOT EXISTS alarm_journal_by_alarm ON alarm_journal(alarm, id)";
constexpr std::string_view insert_row =
    "INSERT INTO alarm_journal(t, alarm, device, parameter, state, value, unit, severity, message, user, comment, "
    "shelved_until) VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)";

Result<bool> has_journal(sqlite::Connection& db) {
    auto count = db.query_integer("SELECT count(*) FROM sqlite_schema WHERE type = 'table' AND name = 'alarm_journal'");
    if (!count) return count.error();
    return *count != 0;
}

}  // namespace

Result<std::unique_ptr<AlarmJournal>> AlarmJournal::open(const std::filesystem::path& database, std::chrono::seconds keep,
                                                         std::function<void(const std::string&)> log) {
    auto db = history::open_for_writing(database);
    if (!db) return db.error();
    for (const std::string_view sql : {create_journal, create_by_time, create_by_alarm}) {
        if (auto made = db->execute(sql); !made) return made.error();
    }
    std::unique_ptr<AlarmJournal> journal(new AlarmJournal());
    auto insert = db->prepare(insert_row);
    if (!insert) return insert.error();
    journal->db_ = std::move(*db);
    journal->insert_ = std::move(*insert);
    journal->keep_ = keep;
    journal->log_ = std::move(log);
    // Read here, before any writer may use the connection.
    auto restored = journal->read_last_states();
    if (restored) {
        journal->restored_ = std::move(*restored);
    } else if (journal->log_) {
        journal->log_(fmt::format("alarms: the states of the last run could not be read ({}); every alarm starts normal",
                                  restored.error().message));
    }
    return journal;
}

AlarmJournal::~AlarmJournal() { (void)write_pending(); }

Result<std::map<std::string, RestoredState>> AlarmJournal::read_last_states() {
    std::map<std::string, RestoredState> states;
    auto rows = db_.prepare(
        "SELECT alarm, t, state, value, shelved_until FROM alarm_journal WHERE id IN "
        "(SELECT max(id) FROM alarm_journal GROUP BY alarm)");
    if (!rows) return rows.error();
    for (;;) {
        auto row = rows->step();
        if (!row) return row.error();
        if (!*row) break;
        const auto state = state_named(rows->text(2));
        if (!state) continue;  // a state this version does not know: the alarm starts normal
        RestoredState& restored = states[rows->text(0)];
        restored.state = *state;
        restored.since = from_ms(rows->integer(1));
        if (!rows->is_null(3)) restored.value = rows->real(3);
        if (!rows->is_null(4)) restored.shelved_until = from_ms(rows->integer(4));
    }
    return states;
}

void AlarmJournal::append(const Transitions& transitions) {
    if (transitions.empty()) return;
    {
        std::lock_guard lock(mutex_);
        queue_.insert(queue_.end(), transitions.begin(), transitions.end());
    }
}

Result<void> AlarmJournal::commit(const Transitions& rows) {
    if (auto begun = db_.execute("BEGIN IMMEDIATE"); !begun) return begun.error();
    for (const AlarmTransition& row : rows) {
        insert_.bind(1, to_ms(row.time));
        insert_.bind(2, std::string_view(row.id));
        insert_.bind(3, std::string_view(row.device));
        insert_.bind(4, std::string_view(row.parameter));
        insert_.bind(5, name_of(row.state));
        insert_.bind(6, row.value);
        insert_.bind(7, std::string_view(row.unit));
        insert_.bind(8, name_of(row.severity));
        insert_.bind(9, std::string_view(row.message));
        insert_.bind(10, std::string_view(row.user));
        insert_.bind(11, std::string_view(row.comment));
        if (row.shelved_until) {
            insert_.bind(12, to_ms(*row.shelved_until));
        } else {
            insert_.bind_null(12);
        }
        auto done = insert_.step();
        insert_.reset();
        if (!done) {
            (void)db_.execute("ROLLBACK");
            return done.error();
        }
    }
    // The journal's rows go with the samples of their age.
    const auto now = Clock::now();
    if (now >= next_expiry_) {
        next_expiry_ = now + std::chrono::minutes(1);
        auto expire = db_.prepare("DELETE FROM alarm_journal WHERE t < ?1");
        if (expire) {
            expire->bind(1, to_ms(now) - std::chrono::duration_cast<milliseconds>(keep_).count());
            (void)expire->step();
        }
    }
    if (auto committed = db_.execute("COMMIT"); !committed) {
        (void)db_.execute("ROLLBACK");
        return committed.error();
    }
    return {};
}

Result<void> AlarmJournal::write_pending() {
    Transitions rows;
    {
        std::lock_guard lock(mutex_);
        rows.swap(queue_);
    }
    if (rows.empty()) return {};
    auto committed = commit(rows);
    std::lock_guard lock(mutex_);
    if (!committed) {
        // Kept, in order, in front of what came meanwhile, and tried again at the next commit.
        queue_.insert(queue_.begin(), std::make_move_iterator(rows.begin()), std::make_move_iterator(rows.end()));
        if (!failing_ && log_) log_(fmt::format("alarm journal: {} (kept in memory and retried)", committed.error().message));
        failing_ = true;
        return committed.error();
    }
    if (failing_ && log_) log_("alarm journal: writing again");
    failing_ = false;
    written_ += rows.size();
    ++commits_;
    return {};
}

std::uint64_t AlarmJournal::commits() const {
    std::lock_guard lock(mutex_);
    return commits_;
}

std::uint64_t AlarmJournal::rows_written() const {
    std::lock_guard lock(mutex_);
    return written_;
}

Result<std::vector<JournalRow>> read_journal(sqlite::Connection& db, Clock::time_point from, Clock::time_point to,
                                             std::size_t limit) {
    std::vector<JournalRow> rows;
    auto present = has_journal(db);
    if (!present) return present.error();
    if (!*present) return rows;  // a history file no alarm was written to yet
    auto query = db.prepare(
        "SELECT t, alarm, device, parameter, state, value, unit, severity, message, user, comment FROM alarm_journal "
        "WHERE t >= ?1 AND t <= ?2 ORDER BY t DESC, id DESC LIMIT ?3");
    if (!query) return query.error();
    query->bind(1, to_ms(from));
    query->bind(2, to_ms(to));
    query->bind(3, static_cast<std::int64_t>(limit));
    for (;;) {
        auto row = query->step();
        if (!row) return row.error();
        if (!*row) break;
        JournalRow out;
        out.time = from_ms(query->integer(0));
        out.id = query->text(1);
        out.device = query->text(2);
        out.parameter = query->text(3);
        out.state = query->text(4);
        if (!query->is_null(5)) out.value = query->real(5);
        out.unit = query->text(6);
        out.severity = query->text(7);
        out.message = query->text(8);
        out.user = query->text(9);
        out.comment = query->text(10);
        rows.push_back(std::move(out));
    }
    return rows;
}

std::string journal_json(const std::vector<JournalRow>& rows) {
    nlohmann::json list = nlohmann::json::array();
    for (const JournalRow& row : rows) {
        list.push_back({{"time", iso_time(row.time)},
                        {"alarm", row.id},
                        {"device", row.device},
                        {"parameter", row.parameter},
                        {"state", row.state},
                        {"value", row.value ? nlohmann::json(*row.value) : nlohmann::json(nullptr)},
                        {"unit", row.unit},
                        {"severity", row.severity},
                        {"message", row.message},
                        {"user", row.user},
                        {"comment", row.comment}});
    }
    return nlohmann::json{{"transitions", list}}.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

namespace {
// RFC 4180: a field with a comma, quote or line break is quoted, its quotes doubled.
std::string csv_field(const std::string& text) {
    if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
    std::string out = "\"";
    for (const char c : text) {
        if (c == '"') out += '"';
        out += c;
    }
    return out + '"';
}
}  // namespace

std::string journal_csv(const std::vector<JournalRow>& rows) {
    std::string out = "time,alarm,device,parameter,state,value,unit,severity,message,user,comment\r\n";
    for (const JournalRow& row : rows) {
        out += fmt::format("{},{},{},{},{},{},{},{},{},{},{}\r\n", iso_time(row.time), csv_field(row.id), csv_field(row.device),
                           csv_field(row.parameter), row.state, row.value ? fmt::format("{}", *row.value) : "",
                           csv_field(row.unit), row.severity, csv_field(row.message), csv_field(row.user),
                           csv_field(row.comment));
    }
    return out;
}

}  // namespace loopwire::gateway::alarms
