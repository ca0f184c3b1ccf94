#include "gateway/historian_reader.hpp"

#include <fmt/format.h>

#include "gateway/postgres_history_query.hpp"

namespace loopwire::gateway {
namespace {

constexpr const char* query_canceled = "57014";  // SQLSTATE of a statement stopped by statement_timeout

}  // namespace

// Holds the connection's turn from a successful take() until destroyed.
class HistorianReader::Turn {
public:
    explicit Turn(HistorianReader& reader) : reader_(reader) {}
    ~Turn() {
        if (!held_) return;
        {
            std::lock_guard lock(reader_.mutex_);
            reader_.busy_ = false;
        }
        reader_.turn_ended_.notify_one();
    }
    Turn(const Turn&) = delete;
    Turn& operator=(const Turn&) = delete;

    bool take(std::chrono::milliseconds within) {
        std::unique_lock lock(reader_.mutex_);
        if (!reader_.turn_ended_.wait_for(lock, within, [this] { return !reader_.busy_; })) return false;
        reader_.busy_ = held_ = true;
        return true;
    }

private:
    HistorianReader& reader_;
    bool held_ = false;
};

HistorianReader::HistorianReader(std::string conninfo, std::optional<std::string> password, HistorianLimits limits)
    : conninfo_(std::move(conninfo)), password_(std::move(password)), limits_(limits) {}

Result<void> HistorianReader::connect() {
    if (db_ && !db_->broken()) return {};
    db_.reset();
    auto db = postgres::Connection::connect(conninfo_, password_, limits_.connect_timeout_seconds, application_name);
    if (!db) return db.error();
    const postgres::Parameters timeout{std::to_string(limits_.statement_timeout.count())};
    if (auto bounded = db->run("SELECT set_config('statement_timeout', $1, false)", timeout); !bounded) return bounded.error();
    db_ = std::move(*db);
    return {};
}

// Runs `ask` on the connection, in turn with the other requests, within the bounds.
template <typename T, typename Ask>
Result<T> HistorianReader::with_connection(Ask ask) {
    const auto turn = std::chrono::seconds(limits_.connect_timeout_seconds) + limits_.statement_timeout;
    Turn held(*this);
    if (!held.take(std::chrono::duration_cast<std::chrono::milliseconds>(turn))) {
        return make_error(ErrorKind::timeout, "the historian is still busy with earlier requests; try again");
    }
    if (auto connected = connect(); !connected) return connected.error();
    Result<T> answer = ask(*db_);
    if (!answer && db_->broken()) {
        // The session ended since the last request (the server restarted, an administrator
        // ended it): once more on a new one, so the asker sees no error for it. Reading only,
        // a request is safe to repeat.
        if (auto connected = connect(); !connected) return connected.error();
        answer = ask(*db_);
    }
    if (answer) return answer;
    if (db_->failed_state() == query_canceled) {
        return make_error(ErrorKind::timeout, fmt::format("{}: no answer within {} ms (the statement_timeout of history "
                                                          "queries); ask for a shorter range or fewer parameters",
                                                          db_->server(), limits_.statement_timeout.count()));
    }
    if (db_->broken()) db_.reset();  // the next request connects again
    return answer;
}

Result<std::vector<HistorySeries>> HistorianReader::query(const std::string& gateway, const HistoryQuery& query) {
    return with_connection<std::vector<HistorySeries>>(
        [&](postgres::Connection& db) { return postgres_history::run_query(db, gateway, query); });
}

Result<std::vector<std::string>> HistorianReader::gateways() {
    return with_connection<std::vector<std::string>>([](postgres::Connection& db) -> Result<std::vector<std::string>> {
        auto rows = db.execute("SELECT DISTINCT gateway FROM loopwire_series ORDER BY gateway");
        if (!rows) return rows.error();
        std::vector<std::string> names;
        for (int i = 0; i < rows->rows(); ++i) names.push_back(rows->text(i, 0));
        return names;
    });
}

}  // namespace loopwire::gateway
