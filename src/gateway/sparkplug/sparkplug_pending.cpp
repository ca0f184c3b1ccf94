#include "gateway/sparkplug/sparkplug_pending.hpp"

#include <memory>

#include "gateway/history_schema.hpp"
#include "gateway/history_store.hpp"

namespace loopwire::gateway {
namespace {

using sparkplug::MetricValue;

// The value's kind, beside it: SQLite keeps integers, reals and text, and the payload needs the
// alternative back (an unsigned word is not a signed one, a boolean not an integer).
enum class Kind : std::int64_t { null = 0, signed_integer = 1, unsigned_integer = 2, real = 3, boolean = 4, text = 5 };

void bind_value(sqlite::Statement& statement, int index, const MetricValue& value) {
    std::visit(
        [&](const auto& v) {
            using V = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<V, std::monostate>) {
                statement.bind_null(index);
            } else if constexpr (std::is_same_v<V, std::string>) {
                statement.bind(index, std::string_view(v));
            } else if constexpr (std::is_same_v<V, double>) {
                statement.bind(index, v);
            } else {
                statement.bind(index, static_cast<std::int64_t>(v));
            }
        },
        value);
}

Kind kind_of(const MetricValue& value) { return static_cast<Kind>(value.index()); }

MetricValue value_at(const sqlite::Statement& row, int column, Kind kind) {
    switch (kind) {
        case Kind::signed_integer:
            return row.integer(column);
        case Kind::unsigned_integer:
            return static_cast<std::uint64_t>(row.integer(column));
        case Kind::real:
            return row.real(column);
        case Kind::boolean:
            return row.integer(column) != 0;
        case Kind::text:
            return row.text(column);
        case Kind::null:
            break;
    }
    return std::monostate{};
}

Result<void> insert(sqlite::Connection& db, const std::vector<PendingMetric>& metrics) {
    auto statement = db.prepare(
        "INSERT INTO sparkplug_pending(made_at, device, metric, t, quality, kind, value) VALUES(?1, ?2, ?3, ?4, ?5, "
        "?6, ?7)");
    if (!statement) return statement.error();
    for (const PendingMetric& metric : metrics) {
        statement->bind(1, static_cast<std::int64_t>(metric.made_at));
        statement->bind(2, std::string_view(metric.device));
        statement->bind(3, std::string_view(metric.metric));
        statement->bind(4, static_cast<std::int64_t>(metric.sample.timestamp));
        statement->bind(5, static_cast<std::int64_t>(metric.sample.quality));
        statement->bind(6, static_cast<std::int64_t>(kind_of(metric.sample.value)));
        bind_value(*statement, 7, metric.sample.value);
        auto done = statement->step();
        statement->reset();
        if (!done) return done.error();
    }
    return {};
}

}  // namespace

static_assert(std::variant_size_v<MetricValue> == 6 &&
                  std::is_same_v<std::variant_alternative_t<5, MetricValue>, std::string>,
              "Kind follows MetricValue's alternatives");

Result<std::vector<PendingMetric>> load_sparkplug_pending(const std::filesystem::path& database) {
    auto db = history::open_for_reading(database, sqlite::Connection::Mode::read_only);
    if (!db) return db.error();
    auto statement =
        db->prepare("SELECT made_at, device, metric, t, quality, kind, value FROM sparkplug_pending ORDER BY id");
    if (!statement) return std::vector<PendingMetric>{};  // a file written before the table was: nothing kept
    std::vector<PendingMetric> kept;
    for (;;) {
        auto row = statement->step();
        if (!row) return row.error();
        if (!*row) break;
        PendingMetric metric;
        metric.made_at = static_cast<std::uint64_t>(statement->integer(0));
        metric.device = statement->text(1);
        metric.metric = statement->text(2);
        metric.sample.timestamp = static_cast<std::uint64_t>(statement->integer(3));
        metric.sample.quality = static_cast<std::int32_t>(statement->integer(4));
        metric.sample.value = value_at(*statement, 6, static_cast<Kind>(statement->integer(5)));
        kept.push_back(std::move(metric));
    }
    return kept;
}

SparkplugPending sparkplug_pending_in(HistoryStore& store) {
    SparkplugPending pending;
    pending.add = [&store](std::vector<PendingMetric> metrics) {
        store.run_in_writer([metrics = std::move(metrics)](sqlite::Connection& db) { return insert(db, metrics); });
    };
    pending.clear = [&store] {
        store.run_in_writer([](sqlite::Connection& db) { return db.execute("DELETE FROM sparkplug_pending"); });
    };
    pending.forget_before = [&store](std::uint64_t made_at) {
        store.run_in_writer([made_at](sqlite::Connection& db) {
            auto statement = db.prepare("DELETE FROM sparkplug_pending WHERE made_at < ?1");
            if (!statement) return Result<void>(statement.error());
            statement->bind(1, static_cast<std::int64_t>(made_at));
            auto done = statement->step();
            if (!done) return Result<void>(done.error());
            return Result<void>();
        });
    };
    return pending;
}

}  // namespace loopwire::gateway
