// The history's forwarding to PostgreSQL (gateway/history_forwarder.hpp) against a real server
// that each test starts (tests/support/postgres_server.hpp): rows arrive exactly once and in
// order, many gateways share one database, a stopped server, a wrong password, a missing
// database and a newer schema are survived or refused clearly, a SIGKILL during a forward loses
// and doubles nothing, and the day partitions are made ahead and dropped after `keep`.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <atomic>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <mutex>
#include <thread>

#include <fmt/format.h>

#include "gateway/gateway.hpp"
#include "gateway/history_store.hpp"
#include "gateway/postgres_database.hpp"
#include "gateway/postgres_history_query.hpp"
#include "gateway/postgres_history_schema.hpp"
#include "support/eventually.hpp"
#include "support/history_parts.hpp"
#include "support/history_test_support.hpp"
#include "support/log_lines.hpp"
#include "support/postgres_server.hpp"

extern char** environ;

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using std::chrono::milliseconds;
using test::PostgresServer;
using loopwire::testing::HistoryParts;
using loopwire::testing::HistoryPartsOptions;
using loopwire::testing::TempFolder;
using loopwire::testing::eventually;
using loopwire::testing::VirtualWall;

// 2026-01-01T00:00:00Z.
const SystemTime t0 = SystemTime(std::chrono::seconds(1767225600));
const std::int64_t t0_ms = 1767225600000;

// Log lines, kept for the checks; thread-safe (the forwarder's thread logs).
using Logs = loopwire::testing::LogLines;

ValueChange number(const std::string& device, const std::string& parameter, double value, SystemTime sampled) {
    ValueChange change;
    change.device = device;
    change.parameter = parameter;
    change.unit = "°C";
    change.status = "ok";
    change.value = device::EngineeringValue{value, "ok", 0, ""};
    change.sampled = sampled;
    return change;
}

// The store on virtual time, with neither thread: the test writes and forwards.
HistoryPartsOptions forwarding(const std::filesystem::path& file, const VirtualWall& wall, const std::string& conninfo,
                          const std::string& gateway = "plant1") {
    HistoryPartsOptions options;
    options.database = file;
    options.wall_clock = wall.clock();
    options.heartbeat = std::chrono::hours(24);  // only the rows the tests record
    ForwardOptions forward;
    forward.conninfo = conninfo;
    forward.gateway = gateway;
    forward.thread = false;
    forward.connect_timeout_seconds = 30;
    options.forward = forward;
    return options;
}

postgres::Connection connect(const PostgresServer& server, const std::string& database = "postgres") {
    auto db = postgres::Connection::connect(server.conninfo(database), std::nullopt, 30);
    if (!db) throw std::runtime_error(db.error().message);
    return std::move(*db);
}

long long scalar(postgres::Connection& db, const std::string& sql) {
    auto result = db.execute(sql);
    if (!result) throw std::runtime_error(result.error().message);
    return result->integer(0, 0);
}

// The values of one gateway's series in the historian, in time order.
std::vector<long long> values_of(postgres::Connection& db, const std::string& gateway, const std::string& parameter) {
    auto rows = db.execute(
        "SELECT s.value FROM loopwire_samples s JOIN loopwire_series n ON n.id = s.series_id "
        "WHERE n.gateway = $1 AND n.parameter = $2 ORDER BY s.t",
        {gateway, parameter});
    if (!rows) throw std::runtime_error(rows.error().message);
    std::vector<long long> values;
    for (int i = 0; i < rows->rows(); ++i) values.push_back(std::stoll(rows->text(i, 0)));
    return values;
}

std::vector<long long> counting(long long n) {
    std::vector<long long> values(static_cast<std::size_t>(n));
    for (long long i = 0; i < n; ++i) values[static_cast<std::size_t>(i)] = i;
    return values;
}

// Records values 0..n-1 of one parameter, a second apart from `from`, and commits them locally.
void record_counting(HistoryParts& store, long long n, const std::string& device = "oven1",
                     const std::string& parameter = "measured_value", SystemTime from = t0) {
    for (long long i = 0; i < n; ++i) store.record(number(device, parameter, static_cast<double>(i), from + std::chrono::seconds(i)));
    ASSERT_TRUE(store.write_pending());
}

class HistoryForward : public ::testing::Test {
protected:
    void SetUp() override {
        if (auto reason = PostgresServer::unavailable()) GTEST_SKIP() << *reason;
        server = std::make_unique<PostgresServer>(
            "local all pwuser scram-sha-256\nlocal all all trust\n");
    }
    std::unique_ptr<PostgresServer> server;
    TempFolder folder;
    VirtualWall wall{t0 + std::chrono::hours(1)};
};

TEST_F(HistoryForward, ShipsEveryRowOnceWithItsMinutesAndEmptiesTheOutbox) {
    auto store = HistoryParts::open(forwarding(folder.path / "h.db", wall, server->url()));
    ASSERT_TRUE(store) << store.error().message;
    record_counting(**store, 150);  // two and a half minutes
    EXPECT_EQ((*store)->forward_stats()->forwarded_total, 0u);
    auto shipped = (*store)->forwarder()->forward_pending();
    ASSERT_TRUE(shipped) << shipped.error().message;
    EXPECT_EQ(*shipped, 150u);
    auto db = connect(*server);
    EXPECT_EQ(values_of(db, "plant1", "measured_value"), counting(150));
    // Minute 0 holds 0..59: min 0, max 59, sum 1770, 60 samples; minute 2 holds 120..149.
    auto minutes = db.execute("SELECT minute - $1, lo, hi, total, n FROM loopwire_minutes ORDER BY minute",
                              {std::to_string(t0_ms / 60000)});
    ASSERT_TRUE(minutes);
    ASSERT_EQ(minutes->rows(), 3);
    EXPECT_EQ(minutes->text(0, 1) + " " + minutes->text(0, 2) + " " + minutes->text(0, 3) + " " + minutes->text(0, 4),
              "0 59 1770 60");
    EXPECT_EQ(minutes->text(2, 0) + " " + minutes->text(2, 4), "2 30");
    const ForwardStats stats = *(*store)->forward_stats();
    EXPECT_EQ(stats.waiting_rows, 0u);
    EXPECT_EQ(stats.forwarded_total, 150u);
    EXPECT_EQ(stats.errors_total, 0u);
    // Forwarding again sends nothing: the outbox is empty.
    auto again = (*store)->forwarder()->forward_pending();
    ASSERT_TRUE(again);
    EXPECT_EQ(*again, 0u);
    EXPECT_EQ(scalar(db, "SELECT count(*) FROM loopwire_samples"), 150);
    EXPECT_EQ(scalar(db, "SELECT version FROM loopwire_schema_version"), postgres_history::schema_version);
}

// A crash after PostgreSQL committed a batch and before the outbox was cleared: the batch is
// sent again, and neither its samples nor its minutes count twice. The outbox is refilled by
// hand, as the crash would have left it, so the resend is certain rather than a race.
// The audit's rows of the file as the historian has them, oldest first: "front device parameter old→new outcome".
std::vector<std::string> writes_of(postgres::Connection& db, const std::string& gateway) {
    auto rows = db.execute(
        "SELECT front || ' ' || peer || ' ' || device || ' ' || parameter || ' ' || old_value || '→' || new_value || ' ' || "
        "outcome || ' ' || (extract(epoch FROM time) * 1000)::bigint - t FROM loopwire_writes WHERE gateway = $1 ORDER BY t, local_id",
        {gateway});
    if (!rows) throw std::runtime_error(rows.error().message);
    std::vector<std::string> writes;
    for (int i = 0; i < rows->rows(); ++i) writes.push_back(rows->text(i, 0));
    return writes;
}

AuditRecord audited(const std::string& front, const std::string& new_value, SystemTime time) {
    AuditRecord record;
    record.time = time;
    record.origin = {front, front == "http" ? "127.0.0.1" : "broker", ""};
    record.device = "oven1";
    record.parameter = "set_point";
    record.old_value = "150 °C";
    record.new_value = new_value;
    record.outcome = "confirmed";
    return record;
}

TEST_F(HistoryForward, TheAuditOfWritesGoesToTheHistorianOnceEach) {
    auto store = HistoryParts::open(forwarding(folder.path / "h.db", wall, server->url()));
    ASSERT_TRUE(store) << store.error().message;
    (*store)->store->record_write(audited("http", "160 °C", t0));
    (*store)->store->record_write(audited("mqtt", "170 °C", t0));  // the same ms: told apart by its id
    ASSERT_TRUE((*store)->write_pending());
    auto shipped = (*store)->forwarder()->forward_pending();
    ASSERT_TRUE(shipped) << shipped.error().message;
    auto db = connect(*server);
    EXPECT_EQ(writes_of(db, "plant1"), (std::vector<std::string>{"http 127.0.0.1 oven1 set_point 150 °C→160 °C confirmed 0",
                                                                 "mqtt broker oven1 set_point 150 °C→170 °C confirmed 0"}));
    // Nothing new: nothing sent again; a new one alone.
    ASSERT_TRUE((*store)->forwarder()->forward_pending());
    (*store)->store->record_write(audited("sparkplug", "180 °C", t0 + 1s));
    ASSERT_TRUE((*store)->write_pending());
    ASSERT_TRUE((*store)->forwarder()->forward_pending());
    EXPECT_EQ(writes_of(db, "plant1").size(), 3u);
    // A forwarder that starts again (a new connection) asks the historian where it is: no row twice.
    store->reset();
    auto again = HistoryParts::open(forwarding(folder.path / "h.db", wall, server->url()));
    ASSERT_TRUE(again) << again.error().message;
    ASSERT_TRUE((*again)->forwarder()->forward_pending());
    EXPECT_EQ(writes_of(db, "plant1").size(), 3u);
    // The table dropped under it: made again and filled again from the file.
    ASSERT_TRUE(db.run("DROP TABLE loopwire_writes"));
    (*again)->store->record_write(audited("http", "190 °C", t0 + 2s));
    ASSERT_TRUE((*again)->write_pending());
    auto refilled = (*again)->forwarder()->forward_pending();
    ASSERT_TRUE(refilled) << refilled.error().message;
    EXPECT_EQ(writes_of(db, "plant1").size(), 4u);
}

TEST_F(HistoryForward, ABatchSentAgainAddsNoSamplesNorMinutes) {
    const auto file = folder.path / "h.db";
    auto store = HistoryParts::open(forwarding(file, wall, server->url()));
    ASSERT_TRUE(store) << store.error().message;
    record_counting(**store, 150);
    ASSERT_TRUE((*store)->forwarder()->forward_pending());
    {
        auto local = sqlite::Connection::open(file.string(), sqlite::Connection::Mode::read_write_create);
        ASSERT_TRUE(local);
        ASSERT_TRUE(local->execute("INSERT INTO outbox(series_id, t) SELECT series_id, t FROM samples ORDER BY t"));
    }
    for (int i = 150; i < 180; ++i) (*store)->record(number("oven1", "measured_value", i, t0 + std::chrono::seconds(i)));
    ASSERT_TRUE((*store)->write_pending());  // and new rows behind them
    auto shipped = (*store)->forwarder()->forward_pending();
    ASSERT_TRUE(shipped) << shipped.error().message;
    auto db = connect(*server);
    EXPECT_EQ(values_of(db, "plant1", "measured_value"), counting(180));
    EXPECT_EQ(scalar(db, "SELECT sum(n) FROM loopwire_minutes"), 180);
    EXPECT_EQ(scalar(db, "SELECT sum(total)::bigint FROM loopwire_minutes"), 180 * 179 / 2);
    EXPECT_EQ(scalar(db, "SELECT max(hi)::bigint FROM loopwire_minutes"), 179);
    EXPECT_EQ((*store)->forward_stats()->waiting_rows, 0u);
}

// The historian's series ids are learnt a batch at a time: series new in a later batch, one the
// historian already has (added by an earlier connection), several in one batch.
TEST_F(HistoryForward, SeriesNewInAnyBatchGetTheirOwnIdsAndRows) {
    HistoryPartsOptions options = forwarding(folder.path / "h.db", wall, server->url());
    options.forward->batch_rows = 4;
    auto store = HistoryParts::open(options);
    ASSERT_TRUE(store) << store.error().message;
    for (int i = 0; i < 6; ++i) (*store)->record(number("oven1", "measured_value", i, t0 + std::chrono::seconds(i)));
    for (int i = 0; i < 6; ++i) {
        (*store)->record(number("oven1", "set_point", 100 + i, t0 + std::chrono::seconds(10 + i)));
        (*store)->record(number("oven2", "measured_value", 200 + i, t0 + std::chrono::seconds(10 + i)));
    }
    ASSERT_TRUE((*store)->write_pending());
    auto admin = connect(*server);
    ASSERT_TRUE(check_forward_target(options.forward.value()));
    // Known to the historian before this gateway's forwarder asks for it.
    ASSERT_TRUE(admin.run("INSERT INTO loopwire_series(gateway, device, parameter, unit) VALUES ('plant1', 'oven1', 'set_point', '°C')"));
    auto shipped = (*store)->forwarder()->forward_pending();
    ASSERT_TRUE(shipped) << shipped.error().message;
    EXPECT_EQ(*shipped, 18u);
    auto rows = admin.execute(
        "SELECT n.device || '/' || n.parameter, string_agg(s.value::text, ',' ORDER BY s.t) FROM loopwire_samples s "
        "JOIN loopwire_series n ON n.id = s.series_id WHERE n.gateway = 'plant1' GROUP BY 1 ORDER BY 1");
    ASSERT_TRUE(rows);
    ASSERT_EQ(rows->rows(), 3);
    EXPECT_EQ(rows->text(0, 0) + " " + rows->text(0, 1), "oven1/measured_value 0,1,2,3,4,5");
    EXPECT_EQ(rows->text(1, 0) + " " + rows->text(1, 1), "oven1/set_point 100,101,102,103,104,105");
    EXPECT_EQ(rows->text(2, 0) + " " + rows->text(2, 1), "oven2/measured_value 200,201,202,203,204,205");
    EXPECT_EQ(scalar(admin, "SELECT count(*) FROM loopwire_series"), 3);
}

TEST_F(HistoryForward, TextsStatusesAndGapsTravelAsTheyAre) {
    auto store = HistoryParts::open(forwarding(folder.path / "h.db", wall, server->conninfo()));
    ASSERT_TRUE(store) << store.error().message;
    ValueChange label = number("oven1", "mode", 2, t0);
    // Every character COPY's text format escapes, and a quote for good measure.
    label.value = device::EngineeringValue{std::string("ramp \"up\",\t\\fast\\\r\n"), "ok", 2, ""};
    label.text = "ramp \"up\",\t\\fast\\\r\n";
    (*store)->record(label);
    ValueChange silent = number("oven1", "measured_value", 0, t0 + 1s);
    silent.value.reset();
    silent.status = "no-reply";
    (*store)->record(silent);
    ASSERT_TRUE((*store)->write_pending());
    ASSERT_TRUE((*store)->forwarder()->forward_pending());
    auto db = connect(*server);
    auto rows = db.execute("SELECT coalesce(value::text, 'null'), coalesce(text, 'null'), coalesce(status, 'ok') "
                           "FROM loopwire_samples ORDER BY t");
    ASSERT_TRUE(rows);
    ASSERT_EQ(rows->rows(), 2);
    EXPECT_EQ(rows->text(0, 0) + "|" + rows->text(0, 1) + "|" + rows->text(0, 2), "2|ramp \"up\",\t\\fast\\\r\n|ok");
    EXPECT_EQ(rows->text(1, 0) + "|" + rows->text(1, 1) + "|" + rows->text(1, 2), "null|null|no-reply");
}

TEST_F(HistoryForward, TwoGatewaysShareOneDatabaseAndStayApart) {
    auto north = HistoryParts::open(forwarding(folder.path / "north.db", wall, server->url(), "north"));
    auto south = HistoryParts::open(forwarding(folder.path / "south.db", wall, server->url(), "south"));
    ASSERT_TRUE(north && south);
    // The same device and parameter names on both: the gateway's name keeps them apart.
    record_counting(**north, 30);
    for (int i = 0; i < 20; ++i) (*south)->record(number("oven1", "measured_value", 1000 + i, t0 + std::chrono::seconds(i)));
    ASSERT_TRUE((*south)->write_pending());
    // Forwarded at once from two threads, as two gateways would.
    std::thread other([&] { EXPECT_TRUE((*south)->forwarder()->forward_pending()); });
    EXPECT_TRUE((*north)->forwarder()->forward_pending());
    other.join();
    auto db = connect(*server);
    EXPECT_EQ(values_of(db, "north", "measured_value"), counting(30));
    std::vector<long long> expected;
    for (int i = 0; i < 20; ++i) expected.push_back(1000 + i);
    EXPECT_EQ(values_of(db, "south", "measured_value"), expected);
    EXPECT_EQ(scalar(db, "SELECT count(DISTINCT gateway) FROM loopwire_series"), 2);
}

// A row as both sides hold it: device, parameter, unit, t, value (in thousandths), text, status.
using RowKey = std::string;

// One gateway's rows in its own file, those stamped at or after `from` ms.
std::multiset<RowKey> local_rows(const std::filesystem::path& file, std::int64_t from) {
    auto db = sqlite::Connection::open(file.string(), sqlite::Connection::Mode::read_only);
    if (!db) throw std::runtime_error(db.error().message);
    auto rows = db->prepare(
        "SELECT r.device || '|' || r.parameter || '|' || r.unit || '|' || s.t || '|' || coalesce(CAST(round(s.value * 1000) AS INTEGER), '-') "
        "|| '|' || coalesce(s.text, '-') || '|' || coalesce(s.status, 'ok') FROM samples s JOIN series r ON r.id = s.series_id "
        "WHERE s.t >= ?1");
    if (!rows) throw std::runtime_error(rows.error().message);
    rows->bind(1, from);
    std::multiset<RowKey> keys;
    for (;;) {
        auto step = rows->step();
        if (!step) throw std::runtime_error(step.error().message);
        if (!*step) break;
        keys.insert(rows->text(0));
    }
    return keys;
}

// Every row of the historian, by the gateway whose series it is filed under.
std::map<std::string, std::multiset<RowKey>> historian_rows(postgres::Connection& db) {
    auto rows = db.execute(
        "SELECT n.gateway, n.device || '|' || n.parameter || '|' || n.unit || '|' || s.t || '|' || "
        "coalesce((round(s.value * 1000)::bigint)::text, '-') || '|' || coalesce(s.text, '-') || '|' || "
        "coalesce(s.status, 'ok') FROM loopwire_samples s JOIN loopwire_series n ON n.id = s.series_id");
    if (!rows) throw std::runtime_error(rows.error().message);
    std::map<std::string, std::multiset<RowKey>> keys;
    for (int i = 0; i < rows->rows(); ++i) keys[rows->text(i, 0)].insert(rows->text(i, 1));
    return keys;
}

struct RowCount {
    long long missing = 0;     // a row of the gateway's file the historian lacks under its series
    long long duplicated = 0;  // a row of the file the historian holds more than once
    long long misfiled = 0;    // a row under the gateway's series that its file does not hold
};

// Row by row: the historian's rows of `gateway` against its file's; `expected` must all be there,
// `allowed` (a superset: the rows before a drop may or may not be) are the only ones that may.
RowCount compare_rows(const std::multiset<RowKey>& held, const std::multiset<RowKey>& expected,
                      const std::multiset<RowKey>& allowed) {
    RowCount count;
    for (const RowKey& key : expected) {
        if (held.count(key) == 0) ++count.missing;
    }
    for (auto it = held.begin(); it != held.end(); it = held.upper_bound(*it)) {
        const auto n = static_cast<long long>(held.count(*it));
        if (allowed.count(*it) == 0) {
            count.misfiled += n;
        } else if (n > 1) {
            count.duplicated += n - 1;
        }
    }
    return count;
}

// Records `n` rows of three series a second apart from `from`, values from `first` up (each
// gateway its own values, so a row filed under the other gateway's series cannot pass for one
// of that gateway's own), and commits them locally.
void record_three_series(HistoryParts& store, int n, double first, SystemTime from) {
    const char* const series[][2] = {{"oven1", "measured_value"}, {"oven1", "set_point"}, {"oven2", "measured_value"}};
    for (int i = 0; i < n; ++i) {
        for (const auto& [device, parameter] : series) {
            store.record(number(device, parameter, first + i, from + std::chrono::seconds(i)));
        }
    }
    ASSERT_TRUE(store.write_pending());
}

// The historian's tables dropped under a forwarding gateway: its next batch makes them again and
// goes in. Dropped again and made again by another gateway, whose series take the ids the first
// one had learnt: the first one's rows still go under its own series, never the other's, and are
// counted as forwarded only once there. Each gateway's file and the historian agree row by row.
TEST_F(HistoryForward, TablesDroppedAndMadeAgainUnderAForwardingGatewayKeepEveryRowUnderItsOwnSeries) {
    const auto north_file = folder.path / "north.db", south_file = folder.path / "south.db";
    auto north = HistoryParts::open(forwarding(north_file, wall, server->url(), "north"));
    ASSERT_TRUE(north) << north.error().message;
    auto admin = connect(*server);
    const std::string drop_all =
        "DROP TABLE loopwire_samples, loopwire_minutes, loopwire_series, loopwire_schema_version CASCADE";  // and the view
    record_three_series(**north, 50, 0, t0);
    ASSERT_TRUE((*north)->forwarder()->forward_pending());

    // Dropped: the next batch finds no table, makes them again and goes in, in the same round.
    ASSERT_TRUE(admin.run(drop_all));
    record_three_series(**north, 50, 50, t0 + 50s);
    auto again = (*north)->forwarder()->forward_pending();
    ASSERT_TRUE(again) << again.error().message;
    EXPECT_EQ(*again, 150u);
    EXPECT_EQ(scalar(admin, "SELECT count(*) FROM loopwire_samples"), 150);
    EXPECT_EQ(scalar(admin, "SELECT count(*) FROM loopwire_values"), 150);  // the view made again too

    // Dropped and made again by another gateway's first connect: south's series are 1, 2, 3,
    // the ids north learnt for its own.
    ASSERT_TRUE(admin.run(drop_all));
    auto south = HistoryParts::open(forwarding(south_file, wall, server->url(), "south"));
    ASSERT_TRUE(south) << south.error().message;
    record_three_series(**south, 40, 100000, t0 + 100s);
    ASSERT_TRUE((*south)->forwarder()->forward_pending());
    EXPECT_EQ(scalar(admin, "SELECT max(id) FROM loopwire_series"), 3);
    const std::uint64_t north_before = (*north)->forward_stats()->forwarded_total;
    record_three_series(**north, 60, 200, t0 + 100s);
    auto shipped = (*north)->forwarder()->forward_pending();
    ASSERT_TRUE(shipped) << shipped.error().message;
    EXPECT_EQ(*shipped, 180u);
    EXPECT_EQ((*north)->forward_stats()->forwarded_total, north_before + 180);
    EXPECT_EQ((*north)->forward_stats()->waiting_rows, 0u);

    // Row by row: north's rows since the last drop and all of south's, each once, each under
    // its own gateway's series; nothing else.
    const auto held = historian_rows(admin);
    const auto north_expected = local_rows(north_file, t0_ms + 100000);
    const auto south_expected = local_rows(south_file, 0);
    ASSERT_EQ(north_expected.size(), 180u);
    ASSERT_EQ(south_expected.size(), 120u);
    EXPECT_EQ(held.size(), 2u);
    const auto in = [&](const std::string& gateway) { return held.count(gateway) ? held.at(gateway) : std::multiset<RowKey>{}; };
    const RowCount n = compare_rows(in("north"), north_expected, north_expected);
    const RowCount s = compare_rows(in("south"), south_expected, south_expected);
    std::cout << fmt::format("north: {} rows held, {} missing, {} duplicated, {} misfiled; south: {} rows held, {} missing, "
                             "{} duplicated, {} misfiled\n",
                             in("north").size(), n.missing, n.duplicated, n.misfiled, in("south").size(), s.missing,
                             s.duplicated, s.misfiled);
    EXPECT_EQ(n.missing + n.duplicated + n.misfiled, 0);
    EXPECT_EQ(s.missing + s.duplicated + s.misfiled, 0);
    EXPECT_EQ(values_of(admin, "south", "measured_value").size(), 80u);  // oven1's and oven2's
}

TEST_F(HistoryForward, AStoppedServerKeepsRowsWaitingLocallyThenGetsEachOnceInOrder) {
    auto store = HistoryParts::open(forwarding(folder.path / "h.db", wall, server->url()));
    ASSERT_TRUE(store);
    record_counting(**store, 40);
    ASSERT_TRUE((*store)->forwarder()->forward_pending());
    server->stop();
    // Recording and the local writer go on; forwarding fails and counts it.
    record_counting(**store, 100, "oven1", "measured_value", t0 + 40s);
    ForwardStats stats = *(*store)->forward_stats();
    EXPECT_EQ(stats.waiting_rows, 100u);
    // The first attempt finds its connection closed by the server, the next cannot connect.
    EXPECT_FALSE((*store)->forwarder()->forward_pending());
    auto failed = (*store)->forwarder()->forward_pending();
    ASSERT_FALSE(failed);
    EXPECT_THAT(failed.error().message, HasSubstr("check the server runs"));
    stats = *(*store)->forward_stats();
    EXPECT_EQ(stats.waiting_rows, 100u);
    EXPECT_EQ(stats.errors_total, 2u);
    EXPECT_NEAR(stats.oldest_waiting_seconds, 3600.0 - 40.0, 0.01);  // the wall is at t0 + 1 h
    server->start();
    auto shipped = (*store)->forwarder()->forward_pending();
    ASSERT_TRUE(shipped) << shipped.error().message;
    EXPECT_EQ(*shipped, 100u);
    auto db = connect(*server);
    auto values = values_of(db, "plant1", "measured_value");
    std::vector<long long> expected = counting(40);
    for (long long i = 0; i < 100; ++i) expected.push_back(i);
    EXPECT_EQ(values, expected);
    EXPECT_EQ((*store)->forward_stats()->waiting_rows, 0u);
}

// The forwarder's own thread: an outage is logged once however often it retries, and its end
// once; rows recorded meanwhile all arrive.
TEST_F(HistoryForward, TheThreadRetriesWithBackOffAndLogsAnOutageOnce) {
    Logs logs;
    HistoryPartsOptions options = forwarding(folder.path / "h.db", wall, server->url());
    options.forward->thread = true;
    options.forward->idle_poll = 20ms;
    options.forward->retry_first = 20ms;
    options.forward->retry_max = 100ms;
    options.log = logs.sink();
    server->stop();
    auto store = HistoryParts::open(options);
    ASSERT_TRUE(store);
    record_counting(**store, 50);
    ASSERT_TRUE(eventually([&] { return (*store)->forward_stats()->errors_total >= 5; }, 120s))
        << "the forwarder did not retry";
    EXPECT_EQ(logs.count("forwarding paused"), 1);
    server->start();
    // The end of the outage is logged once the batch is in, a moment after the count moved.
    ASSERT_TRUE(eventually(
        [&] { return (*store)->forward_stats()->forwarded_total >= 50 && logs.count("forwarding again") > 0; }, 120s))
        << "the rows did not arrive once the server was back";
    EXPECT_EQ(logs.count("forwarding again"), 1);
    EXPECT_EQ(logs.count("forwarding paused"), 1);
    auto db = connect(*server);
    EXPECT_EQ(values_of(db, "plant1", "measured_value"), counting(50));
}

TEST_F(HistoryForward, AWrongPasswordIsRefusedClearlyAtCheckAndRetriedAtRunTime) {
    auto admin = connect(*server);
    ASSERT_TRUE(admin.run("CREATE ROLE pwuser LOGIN PASSWORD 'right'"));
    ASSERT_TRUE(admin.run("GRANT CREATE ON SCHEMA public TO pwuser"));
    ForwardOptions target;
    target.conninfo = server->conninfo("postgres", "pwuser");
    target.password = "wrong";
    auto refused = check_forward_target(target);
    ASSERT_FALSE(refused);
    EXPECT_THAT(refused.error().message, HasSubstr("password authentication failed"));
    EXPECT_THAT(refused.error().message, HasSubstr("password_file"));
    EXPECT_THAT(refused.error().message, ::testing::Not(HasSubstr("wrong")));
    target.password = "right";
    EXPECT_TRUE(check_forward_target(target));

    // At run time: the store opens and records; forwarding fails until the password is right.
    HistoryPartsOptions options = forwarding(folder.path / "h.db", wall, server->conninfo("postgres", "pwuser"));
    options.forward->password = "wrong";
    {
        auto store = HistoryParts::open(options);
        ASSERT_TRUE(store);
        record_counting(**store, 10);
        EXPECT_FALSE((*store)->forwarder()->forward_pending());
        EXPECT_EQ((*store)->forward_stats()->waiting_rows, 10u);
    }
    options.forward->password = "right";
    auto store = HistoryParts::open(options);
    ASSERT_TRUE(store);
    auto shipped = (*store)->forwarder()->forward_pending();
    ASSERT_TRUE(shipped) << shipped.error().message;
    EXPECT_EQ(*shipped, 10u);
}

TEST_F(HistoryForward, AMissingDatabaseIsRefusedClearlyAndRowsWaitUntilItExists) {
    ForwardOptions target;
    target.conninfo = server->url("plant");
    auto refused = check_forward_target(target);
    ASSERT_FALSE(refused);
    EXPECT_THAT(refused.error().message, HasSubstr("database \"plant\" does not exist"));
    EXPECT_THAT(refused.error().message, HasSubstr("createdb"));
    auto store = HistoryParts::open(forwarding(folder.path / "h.db", wall, server->url("plant")));
    ASSERT_TRUE(store);
    record_counting(**store, 5);
    EXPECT_FALSE((*store)->forwarder()->forward_pending());
    auto admin = connect(*server);
    ASSERT_TRUE(admin.run("CREATE DATABASE plant"));
    auto shipped = (*store)->forwarder()->forward_pending();
    ASSERT_TRUE(shipped) << shipped.error().message;
    EXPECT_EQ(*shipped, 5u);
}

TEST_F(HistoryForward, ANewerSchemaIsRefusedWithItsVersion) {
    ForwardOptions target;
    target.conninfo = server->url();
    ASSERT_TRUE(check_forward_target(target));
    auto admin = connect(*server);
    ASSERT_TRUE(admin.run("UPDATE loopwire_schema_version SET version = 7"));
    auto refused = check_forward_target(target);
    ASSERT_FALSE(refused);
    EXPECT_THAT(refused.error().message, HasSubstr("schema version 7, written by a newer loopwire"));
}

// A historian made by a loopwire of schema version 1 gets version 2's index of the samples
// without a value (what finds the gaps of a long range), and its version says so.
TEST_F(HistoryForward, AVersion1SchemaIsUpgraded) {
    ForwardOptions target;
    target.conninfo = server->url();
    ASSERT_TRUE(check_forward_target(target));
    auto admin = connect(*server);
    ASSERT_TRUE(admin.run("DROP INDEX loopwire_samples_gaps"));
    ASSERT_TRUE(admin.run("UPDATE loopwire_schema_version SET version = 1"));
    ASSERT_TRUE(check_forward_target(target));
    EXPECT_EQ(scalar(admin, "SELECT version FROM loopwire_schema_version"), 2);
    EXPECT_EQ(scalar(admin, "SELECT count(*) FROM pg_indexes WHERE indexname = 'loopwire_samples_gaps'"), 1);
}

// --check's message names the configuration's line and key, then what the server said.
TEST_F(HistoryForward, CheckNamesTheKeyAndTheRemedy) {
    GatewayConfig config;
    config.name = "plant1";
    HistoryConfig history;
    history.forward_to = server->url("missing");
    history.written_at = "plant.toml:12";
    config.history = history;
    auto refused = check_history_forwarding(config);
    ASSERT_FALSE(refused);
    EXPECT_THAT(refused.error().message, HasSubstr("plant.toml:12: history.forward_to:"));
    EXPECT_THAT(refused.error().message, HasSubstr("create the database"));
    config.history->forward_to = server->url();
    EXPECT_TRUE(check_history_forwarding(config));
}

TEST_F(HistoryForward, DayPartitionsAreMadeAheadAndDroppedAfterKeep) {
    HistoryPartsOptions options = forwarding(folder.path / "h.db", wall, server->url());
    options.keep = std::chrono::hours(72);
    auto store = HistoryParts::open(options);
    ASSERT_TRUE(store);
    for (int day = 0; day < 2; ++day) {
        (*store)->record(number("oven1", "measured_value", day, t0 + std::chrono::hours(24 * day)));
    }
    wall.set(t0 + std::chrono::hours(47));  // 2026-01-02 23:00
    ASSERT_TRUE((*store)->write_pending());
    ASSERT_TRUE((*store)->forwarder()->forward_pending());
    auto db = connect(*server);
    const std::string partitions = "SELECT count(*) FROM pg_inherits WHERE inhparent = 'loopwire_samples'::regclass";
    EXPECT_EQ(scalar(db, partitions), 3);  // 2026-01-01 and -02 with rows, and tomorrow's ahead
    EXPECT_EQ(scalar(db, "SELECT count(*) FROM pg_class WHERE relname = 'loopwire_samples_20260103'"), 1);
    wall.set(t0 + std::chrono::hours(24 * 4 + 1));
    ASSERT_TRUE((*store)->forwarder()->drop_expired_partitions());
    // 72 h back from 01-05 01:00 is 01-02 01:00: only 01-01 is wholly older.
    EXPECT_EQ(scalar(db, partitions), 2);
    EXPECT_EQ(scalar(db, "SELECT count(*) FROM pg_class WHERE relname = 'loopwire_samples_20260101'"), 0);
    EXPECT_EQ(scalar(db, "SELECT count(*) FROM loopwire_samples"), 1);
}

// /api/history?gateway=NAME: another gateway's history from the historian, cut into the same
// buckets and gaps as the local file's; the own gateway's from the file.
TEST_F(HistoryForward, AnotherGatewaysHistoryIsAskedFromTheHistorian) {
    auto north = HistoryParts::open(forwarding(folder.path / "north.db", wall, server->url(), "north"));
    auto south = HistoryParts::open(forwarding(folder.path / "south.db", wall, server->url(), "south"));
    ASSERT_TRUE(north && south);
    for (int i = 0; i < 120; ++i) (*south)->record(number("oven1", "measured_value", i, t0 + std::chrono::seconds(i)));
    ValueChange silent = number("oven1", "measured_value", 0, t0 + 120s);
    silent.value.reset();
    silent.status = "no-reply";
    (*south)->record(silent);
    (*south)->record(number("oven1", "measured_value", 7, t0 + 150s));
    ASSERT_TRUE((*south)->write_pending());
    ASSERT_TRUE((*south)->forwarder()->forward_pending());
    HistoryQuery query;
    query.device = "oven1";
    query.parameters = {"measured_value"};
    query.from = t0;
    query.to = t0 + 179999ms;
    query.points = 3;  // one bucket a minute
    const auto local = (*south)->query(query);
    query.gateway = "south";
    const auto remote = (*north)->query(query);
    ASSERT_TRUE(local && remote) << (remote ? local.error().message : remote.error().message);
    ASSERT_EQ(remote->size(), 1u);
    const HistorySeries& series = remote->front();
    ASSERT_EQ(series.buckets.size(), 3u);
    EXPECT_EQ(series.buckets[0].min, 0);
    EXPECT_EQ(series.buckets[0].max, 59);
    EXPECT_EQ(series.buckets[0].count, 60u);
    EXPECT_EQ(series.buckets[2].count, 1u);
    ASSERT_EQ(series.gaps.size(), 1u);
    EXPECT_EQ(series.gaps[0].start, t0 + 120s);
    EXPECT_EQ(series.gaps[0].end, std::optional(t0 + 150s));
    // The same answer as the gateway's own file gives.
    const HistorySeries& mine = local->front();
    ASSERT_EQ(mine.buckets.size(), series.buckets.size());
    for (std::size_t i = 0; i < mine.buckets.size(); ++i) {
        EXPECT_EQ(mine.buckets[i].start, series.buckets[i].start);
        EXPECT_EQ(mine.buckets[i].count, series.buckets[i].count);
        EXPECT_DOUBLE_EQ(mine.buckets[i].mean, series.buckets[i].mean);
    }
    query.gateway = "west";
    auto unknown = (*north)->query(query);
    ASSERT_FALSE(unknown);
    EXPECT_THAT(unknown.error().message, HasSubstr("the historian has no device \"oven1\" of gateway \"west\""));
}

// The value in force at `from` of another gateway's series, from the historian as from the file:
// the last row before `from` when it holds a value read, and no older than twice the asking
// gateway's heartbeat.
TEST_F(HistoryForward, TheValueInForceAtFromComesFromTheHistorianToo) {
    HistoryPartsOptions north_options = forwarding(folder.path / "north.db", wall, server->url(), "north");
    north_options.heartbeat = 60s;
    auto north = HistoryParts::open(north_options);
    auto south = HistoryParts::open(forwarding(folder.path / "south.db", wall, server->url(), "south"));
    ASSERT_TRUE(north && south);
    (*south)->record(number("oven1", "measured_value", 137, t0));
    (*south)->record(number("oven1", "measured_value", 140.5, t0 + 50s));
    ValueChange silent = number("oven1", "measured_value", 0, t0 + 100s);
    silent.value.reset();
    silent.status = "no-reply";
    (*south)->record(silent);
    (*south)->record(number("oven1", "set_point", 250, t0));
    ASSERT_TRUE((*south)->write_pending());
    ASSERT_TRUE((*south)->forwarder()->forward_pending());
    const auto ask_south = [&](const std::string& parameter, SystemTime from) {
        HistoryQuery query;
        query.device = "oven1";
        query.gateway = "south";
        query.parameters = {parameter};
        query.from = from;
        query.to = from + 5min;
        query.points = 600;
        auto answer = (*north)->query(query);
        EXPECT_TRUE(answer) << answer.error().message;
        return answer ? answer->front().before : std::nullopt;
    };
    const auto held = ask_south("measured_value", t0 + 60s);
    ASSERT_TRUE(held);
    EXPECT_EQ(held->time, t0 + 50s);
    EXPECT_EQ(held->value, 140.5);
    EXPECT_FALSE(ask_south("measured_value", t0 + 110s)) << "a row of nothing read: the line starts broken";
    const auto within = ask_south("set_point", t0 + 120s);
    ASSERT_TRUE(within);
    EXPECT_EQ(within->value, 250);
    EXPECT_FALSE(ask_south("set_point", t0 + 121s)) << "older than twice the heartbeat";
}

// The historian's buckets from its raw samples, grouped as `plan` groups them: what the rollup
// must agree with.
std::vector<HistoryBucket> raw_buckets(postgres::Connection& db, const BucketPlan& plan, std::int64_t from, std::int64_t to) {
    auto rows = db.execute(
        "SELECT (t - $1) / $2, min(value), max(value), avg(value), count(*) FROM loopwire_samples "
        "WHERE t >= $3 AND t <= $4 AND value IS NOT NULL GROUP BY 1 ORDER BY 1",
        {std::to_string(plan.origin), std::to_string(plan.width), std::to_string(from), std::to_string(to)});
    if (!rows) throw std::runtime_error(rows.error().message);
    std::vector<HistoryBucket> buckets;
    for (int i = 0; i < rows->rows(); ++i) {
        buckets.push_back({SystemTime(milliseconds(plan.origin + rows->integer(i, 0) * plan.width)), std::stod(rows->text(i, 1)),
                           std::stod(rows->text(i, 2)), std::stod(rows->text(i, 3)), static_cast<std::size_t>(rows->integer(i, 4))});
    }
    return buckets;
}

// Buckets of whole minutes come from the historian's minute rollup, the minutes cut by `from`
// and `to` from its samples: the same min, max, mean and count as the samples alone give, no
// bucket where nothing was sampled, and the gaps as they are.
TEST_F(HistoryForward, TheHistoriansRollupAnswersAsItsSamplesDo) {
    auto store = HistoryParts::open(forwarding(folder.path / "h.db", wall, server->url(), "south"));
    ASSERT_TRUE(store);
    for (int i = 0; i < 600; ++i) {
        if (i >= 240 && i < 360) continue;  // minutes 4 and 5: nothing sampled
        ValueChange change = number("oven1", "measured_value", (i * 37) % 101, t0 + std::chrono::seconds(i));
        if (i == 400) change.value.reset();  // a missed reply: a gap to the next value
        (*store)->record(change);
    }
    ASSERT_TRUE((*store)->write_pending());
    ASSERT_TRUE((*store)->forwarder()->forward_pending());
    auto db = connect(*server);
    HistoryQuery query;
    query.device = "oven1";
    query.from = t0 + 7s;  // minute 0 cut at the start, minute 9 at the end
    query.to = t0 + 587s;
    query.points = 5;  // buckets of two minutes
    const std::int64_t from = t0_ms + 7000, to = t0_ms + 587000;
    const BucketPlan plan = plan_buckets(from, to, query.points);
    ASSERT_TRUE(plan.minutes);
    ASSERT_EQ(plan.width, 120000);
    auto answer = postgres_history::run_query(db, "south", query);
    ASSERT_TRUE(answer) << answer.error().message;
    ASSERT_EQ(answer->size(), 1u);
    const auto& buckets = answer->front().buckets;
    const auto expected = raw_buckets(db, plan, from, to);
    ASSERT_EQ(buckets.size(), 4u);  // of five: the one of minutes 4 and 5 is absent
    ASSERT_EQ(expected.size(), buckets.size());
    for (std::size_t i = 0; i < buckets.size(); ++i) {
        EXPECT_EQ(buckets[i].start, expected[i].start) << i;
        EXPECT_EQ(buckets[i].min, expected[i].min) << i;
        EXPECT_EQ(buckets[i].max, expected[i].max) << i;
        EXPECT_DOUBLE_EQ(buckets[i].mean, expected[i].mean) << i;
        EXPECT_EQ(buckets[i].count, expected[i].count) << i;
    }
    EXPECT_EQ(buckets[2].start, t0 + 6min);
    ASSERT_EQ(answer->front().gaps.size(), 1u);
    EXPECT_EQ(answer->front().gaps[0].start, t0 + 400s);
    EXPECT_EQ(answer->front().gaps[0].end, std::optional(t0 + 401s));
    // The rollup really is what answers for whole minutes, and only for those: a minute altered
    // in the rollup shows, the cut minute 0 altered there does not.
    const std::string minute0 = std::to_string(t0_ms / 60000);
    ASSERT_TRUE(db.run("UPDATE loopwire_minutes SET hi = 1000 WHERE minute = $1 + 1", {minute0}));
    ASSERT_TRUE(db.run("UPDATE loopwire_minutes SET lo = -1000 WHERE minute = $1", {minute0}));
    auto altered = postgres_history::run_query(db, "south", query);
    ASSERT_TRUE(altered);
    EXPECT_EQ(altered->front().buckets[0].max, 1000);
    EXPECT_EQ(altered->front().buckets[0].min, expected[0].min);
    // Buckets under a minute wide are the samples' alone.
    query.points = 100;
    auto fine = postgres_history::run_query(db, "south", query);
    ASSERT_TRUE(fine);
    for (const auto& bucket : fine->front().buckets) EXPECT_LE(bucket.max, 100);
}

#ifdef HISTORY_FORWARD_WORKER
// A gateway killed with SIGKILL while it forwards (a worker process with a full outbox): after a
// restart every row is in the historian exactly once, and the minutes count each once.
TEST_F(HistoryForward, ASigkillDuringAForwardLosesAndDoublesNothing) {
    const long long total = 60000;
    const auto file = folder.path / "h.db";
    {
        HistoryPartsOptions options = forwarding(file, wall, server->url());
        options.max_queued = 2'000'000;
        auto store = HistoryParts::open(options);
        ASSERT_TRUE(store);
        record_counting(**store, total);
        ASSERT_EQ((*store)->forward_stats()->waiting_rows, static_cast<std::uint64_t>(total));
    }
    auto db = connect(*server);
    ASSERT_TRUE(db.run("SELECT 1"));
    std::string worker = HISTORY_FORWARD_WORKER;
    std::string database = file.string();
    std::string url = server->url();
    char* argv[] = {worker.data(), database.data(), url.data(), nullptr};
    pid_t pid = 0;
    ASSERT_EQ(posix_spawn(&pid, worker.c_str(), nullptr, nullptr, argv, environ), 0);
    // Killed as soon as the historian has some rows and not all: in the middle of forwarding.
    long long seen = 0;
    const auto some_forwarded = [&] {
        auto count = db.execute("SELECT count(*) FROM loopwire_samples");
        seen = count ? count->integer(0, 0) : 0;  // the tables may not exist yet
        return seen > 0;
    };
    ASSERT_TRUE(eventually(some_forwarded, 180s, 1ms)) << "the worker forwarded nothing";
    ::kill(pid, SIGKILL);
    int status = 0;
    ::waitpid(pid, &status, 0);
    ASSERT_TRUE(WIFSIGNALED(status));
    ASSERT_LT(seen, total) << "the worker finished before it was killed: the test proves nothing";
    auto store = HistoryParts::open(forwarding(file, wall, server->url()));
    ASSERT_TRUE(store);
    ASSERT_TRUE((*store)->forwarder()->forward_pending());
    EXPECT_EQ(values_of(db, "plant1", "measured_value"), counting(total));
    EXPECT_EQ(scalar(db, "SELECT sum(n) FROM loopwire_minutes"), total);
    EXPECT_EQ(scalar(db, "SELECT sum(total)::bigint FROM loopwire_minutes"), total * (total - 1) / 2);
    EXPECT_EQ((*store)->forward_stats()->waiting_rows, 0u);
}
#endif

}  // namespace
}  // namespace loopwire::gateway
