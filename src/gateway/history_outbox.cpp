#include "gateway/history_outbox.hpp"

#include <fmt/format.h>

#include "gateway/history_schema.hpp"

namespace loopwire::gateway {

Result<Outbox> Outbox::open(const std::filesystem::path& database) {
    auto db = history::open_for_reading(database);
    if (!db) return db.error();
    Outbox outbox;
    outbox.db_ = std::move(*db);
    return outbox;
}

Result<OutboxBatch> Outbox::read(std::int64_t after, std::size_t limit) {
    // LEFT JOIN: an outbox row whose sample retention deleted is still read, so it is cleared.
    auto statement = db_.prepare(
        "SELECT o.seq, o.series_id, o.t, s.t IS NOT NULL, s.value, s.text, s.status FROM outbox o "
        "LEFT JOIN samples s ON s.series_id = o.series_id AND s.t = o.t WHERE o.seq > ?1 ORDER BY o.seq LIMIT ?2");
    if (!statement) return statement.error();
    statement->bind(1, after);
    statement->bind(2, static_cast<std::int64_t>(limit));
    OutboxBatch batch;
    batch.rows.reserve(limit);
    for (;;) {
        auto row = statement->step();
        if (!row) return row.error();
        if (!*row) return batch;
        batch.last_seq = statement->integer(0);
        if (statement->integer(3) == 0) {
            ++batch.expired;
            continue;
        }
        const auto text = [&](int column) { return statement->is_null(column) ? std::nullopt : std::optional(statement->text(column)); };
        batch.rows.push_back({statement->integer(1), statement->integer(2),
                              statement->is_null(4) ? std::nullopt : std::optional(statement->real(4)), text(5), text(6)});
    }
}

Result<void> Outbox::clear(std::int64_t last) {
    auto clear = db_.prepare("DELETE FROM outbox WHERE seq <= ?1");
    if (!clear) return clear.error();
    clear->bind(1, last);
    if (auto cleared = clear->step(); !cleared) return cleared.error();
    return {};
}

Result<SeriesNames> Outbox::names(std::int64_t series) {
    auto names = db_.prepare("SELECT device, parameter, unit FROM series WHERE id = ?1");
    if (!names) return names.error();
    names->bind(1, series);
    auto found = names->step();
    if (!found) return found.error();
    if (!*found) return make_error(ErrorKind::malformed, fmt::format("{}: series {} is missing", db_.file(), series));
    return SeriesNames{names->text(0), names->text(1), names->text(2)};
}

Result<std::vector<LocalWrite>> Outbox::writes_after(std::int64_t t, std::int64_t id, std::size_t limit) {
    auto statement = db_.prepare(
        "SELECT id, t, front, peer, user, device, parameter, old_value, new_value, outcome FROM writes "
        "WHERE t > ?1 OR (t = ?1 AND id > ?2) ORDER BY t, id LIMIT ?3");
    if (!statement) return statement.error();
    statement->bind(1, t);
    statement->bind(2, id);
    statement->bind(3, static_cast<std::int64_t>(limit));
    std::vector<LocalWrite> rows;
    for (;;) {
        auto row = statement->step();
        if (!row) return row.error();
        if (!*row) return rows;
        LocalWrite write{statement->integer(0), statement->integer(1), {}};
        for (int column = 2; column < 10; ++column) write.fields.push_back(statement->text(column));
        rows.push_back(std::move(write));
    }
}

Result<std::int64_t> Outbox::waiting() { return db_.query_integer("SELECT count(*) FROM outbox"); }

Result<std::int64_t> Outbox::oldest_t() {
    return db_.query_integer("SELECT coalesce((SELECT t FROM outbox ORDER BY seq LIMIT 1), 0)");
}

}  // namespace loopwire::gateway
