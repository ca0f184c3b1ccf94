// The reader of other gateways' history in the shared PostgreSQL historian
// (gateway/historian_reader.hpp), against a real server: one connection kept between requests
// and opened again after it broke, a statement bounded by its timeout, a database that is down
// a quick error rather than a wait, and requests from many threads taking turns.
#include "gateway/historian_reader.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/types.h>

#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

#include "gateway/history_store.hpp"
#include "support/eventually.hpp"
#include "support/history_parts.hpp"
#include "support/history_test_support.hpp"
#include "support/postgres_server.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using loopwire::testing::TempFolder;
using loopwire::testing::eventually;
using loopwire::testing::VirtualWall;
using test::PostgresServer;

const SystemTime t0 = SystemTime(std::chrono::seconds(1767225600));  // 2026-01-01T00:00:00Z

postgres::Connection connect(const PostgresServer& server) {
    auto db = postgres::Connection::connect(server.conninfo(), std::nullopt, 30);
    if (!db) throw std::runtime_error(db.error().message);
    return std::move(*db);
}

// The reader's session on the server: its backend's process id, or "" when it has none.
std::string reader_session(postgres::Connection& admin) {
    auto row = admin.execute("SELECT string_agg(pid::text, ',') FROM pg_stat_activity WHERE application_name = $1",
                             {HistorianReader::application_name});
    if (!row) throw std::runtime_error(row.error().message);
    return row->is_null(0, 0) ? "" : row->text(0, 0);
}

class HistorianReaderTest : public ::testing::Test {
protected:
    void SetUp() override {
        if (auto reason = PostgresServer::unavailable()) GTEST_SKIP() << *reason;
        server = std::make_unique<PostgresServer>();
        // A minute of one value a second, forwarded by a gateway called "south".
        loopwire::testing::HistoryPartsOptions options;
        options.database = folder.path / "south.db";
        options.wall_clock = wall.clock();
        options.heartbeat = std::chrono::hours(24);
        ForwardOptions forward;
        forward.conninfo = server->url();
        forward.gateway = "south";
        forward.thread = false;
        options.forward = forward;
        auto store = loopwire::testing::HistoryParts::open(options);
        ASSERT_TRUE(store) << store.error().message;
        for (int i = 0; i < 60; ++i) {
            ValueChange change;
            change.device = "oven1";
            change.parameter = "measured_value";
            change.unit = "°C";
            change.status = "ok";
            change.value = device::EngineeringValue{static_cast<double>(i), "ok", 0, ""};
            change.sampled = t0 + std::chrono::seconds(i);
            (*store)->record(change);
        }
        ASSERT_TRUE((*store)->write_pending());
        auto shipped = (*store)->forwarder()->forward_pending();
        ASSERT_TRUE(shipped) << shipped.error().message;
        query.device = "oven1";
        query.from = t0;
        query.to = t0 + 59s;
        query.points = 1;
    }

    std::unique_ptr<PostgresServer> server;
    TempFolder folder;
    VirtualWall wall{t0 + std::chrono::hours(1)};
    HistoryQuery query;
};

TEST_F(HistorianReaderTest, OneConnectionServesRequestAfterRequestAndIsOpenedAgainAfterItBroke) {
    HistorianReader reader(server->url(), std::nullopt);
    auto admin = connect(*server);
    EXPECT_EQ(reader_session(admin), "");  // nothing before the first request
    for (int i = 0; i < 3; ++i) {
        auto answer = reader.query("south", query);
        ASSERT_TRUE(answer) << answer.error().message;
        ASSERT_EQ(answer->front().buckets.size(), 1u);
        EXPECT_EQ(answer->front().buckets[0].count, 60u);
    }
    const std::string first = reader_session(admin);
    ASSERT_NE(first, "");
    EXPECT_EQ(first.find(','), std::string::npos) << "more than one session: " << first;
    ASSERT_TRUE(admin.run("SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE application_name = $1",
                          {HistorianReader::application_name}));
    // Ending a session is asynchronous: the next request must meet it ended, not ending.
    ASSERT_TRUE(eventually([&] { return reader_session(admin).empty(); }, 60s)) << "the reader's session was not ended";
    // The request that finds the connection broken is asked again on a new one.
    auto again = reader.query("south", query);
    ASSERT_TRUE(again) << again.error().message;
    const std::string second = reader_session(admin);
    EXPECT_NE(second, "");
    EXPECT_NE(second, first);
}

TEST_F(HistorianReaderTest, AStatementPastItsTimeoutIsATimeoutAndTheNextRequestIsServed) {
    HistorianLimits limits;
    limits.statement_timeout = 300ms;
    HistorianReader reader(server->url(), std::nullopt, limits);
    ASSERT_TRUE(reader.query("south", query));
    auto admin = connect(*server);
    // Another session holds the series table: the reader's statement waits, and is stopped.
    ASSERT_TRUE(admin.run("BEGIN"));
    ASSERT_TRUE(admin.run("LOCK TABLE loopwire_series IN ACCESS EXCLUSIVE MODE"));
    auto stopped = reader.query("south", query);
    ASSERT_FALSE(stopped);
    EXPECT_EQ(stopped.error().kind, ErrorKind::timeout);
    EXPECT_THAT(stopped.error().message, HasSubstr("no answer within 300 ms (the statement_timeout of history queries)"));
    ASSERT_TRUE(admin.run("ROLLBACK"));
    auto served = reader.query("south", query);
    ASSERT_TRUE(served) << served.error().message;
    EXPECT_EQ(served->front().buckets[0].count, 60u);
}

TEST_F(HistorianReaderTest, ADatabaseThatIsDownIsALinkErrorUntilItIsBack) {
    HistorianReader reader(server->url(), std::nullopt);
    ASSERT_TRUE(reader.query("south", query));
    server->stop();
    for (int i = 0; i < 2; ++i) {  // on the connection it had, then on a connect that fails
        auto down = reader.query("south", query);
        ASSERT_FALSE(down);
        EXPECT_EQ(down.error().kind, ErrorKind::link) << down.error().message;
    }
    auto refused = reader.gateways();
    ASSERT_FALSE(refused);
    EXPECT_THAT(refused.error().message, HasSubstr("cannot connect"));
    server->start();
    auto back = reader.query("south", query);
    ASSERT_TRUE(back) << back.error().message;
}

TEST_F(HistorianReaderTest, RequestsFromManyThreadsTakeTurnsOnTheConnection) {
    HistorianReader reader(server->url(), std::nullopt);
    std::vector<std::thread> askers;
    std::atomic<int> answered{0};
    for (int t = 0; t < 4; ++t) {
        askers.emplace_back([&] {
            for (int i = 0; i < 5; ++i) {
                auto answer = reader.query("south", query);
                if (answer && answer->front().buckets[0].count == 60u) ++answered;
            }
        });
    }
    for (auto& asker : askers) asker.join();
    EXPECT_EQ(answered.load(), 20);
}

TEST_F(HistorianReaderTest, TheGatewaysAreThoseThatForwardedHistory) {
    HistorianReader reader(server->url(), std::nullopt);
    auto admin = connect(*server);
    ASSERT_TRUE(admin.run("INSERT INTO loopwire_series(gateway, device, parameter, unit) VALUES ('north', 'kiln', 'pv', '')"));
    auto names = reader.gateways();
    ASSERT_TRUE(names) << names.error().message;
    EXPECT_EQ(*names, (std::vector<std::string>{"north", "south"}));
}

// The historian knows no profile: an alias (PV, as the dashboard and the CLI name it) stands
// for what it means in the profile whose meaning the device has a series of (the TC10's
// measured_value, not the AC20's carbon_potential); one the device has nothing for is refused.
TEST_F(HistorianReaderTest, AnAliasIsTheParameterOfTheDeviceItNames) {
    HistorianReader reader(server->url(), std::nullopt);
    query.parameters = {"PV"};
    auto answer = reader.query("south", query);
    ASSERT_TRUE(answer) << answer.error().message;
    ASSERT_EQ(answer->size(), 1u);
    EXPECT_EQ(answer->front().parameter, "measured_value");
    EXPECT_EQ(answer->front().buckets.at(0).count, 60u);
    query.parameters = {"SP"};
    auto refused = reader.query("south", query);
    ASSERT_FALSE(refused);
    EXPECT_THAT(refused.error().message, HasSubstr("device \"oven1\" of gateway \"south\" has no parameter \"SP\""));
}

// A server that stops answering (its backend stopped: the connection stays open, nothing comes
// back) is told of while the statement waits, and its return once it answers, with how long.
TEST_F(HistorianReaderTest, AHistorianThatStopsAnsweringIsLoggedAndSoIsItsReturn) {
    std::mutex mutex;
    std::condition_variable logged;
    std::vector<std::string> lines;
    postgres::StallWatch watch{[&](const std::string& line) {
                                   std::lock_guard lock(mutex);
                                   lines.push_back(line);
                                   logged.notify_all();
                               },
                               300ms};
    auto db = postgres::Connection::connect(server->conninfo(), std::nullopt, 30, "loopwire", watch);
    ASSERT_TRUE(db) << db.error().message;
    auto backend = db->execute("SELECT pg_backend_pid()");
    ASSERT_TRUE(backend) << backend.error().message;
    const auto pid = static_cast<pid_t>(backend->integer(0, 0));
    const auto wait_for_line = [&](std::size_t count) {
        std::unique_lock lock(mutex);
        return logged.wait_for(lock, 60s, [&] { return lines.size() >= count; });
    };
    ASSERT_EQ(::kill(pid, SIGSTOP), 0);
    std::thread asking([&] { EXPECT_TRUE(db->run("SELECT 1")); });
    const bool warned = wait_for_line(1);
    ::kill(pid, SIGCONT);
    asking.join();
    ASSERT_TRUE(warned) << "no warning while the server did not answer";
    ASSERT_TRUE(wait_for_line(2));
    std::lock_guard lock(mutex);
    ASSERT_EQ(lines.size(), 2u);
    EXPECT_THAT(lines[0], ::testing::MatchesRegex("warning: postgresql .* has not answered for [0-9.]+ s: a statement waits .*"));
    EXPECT_THAT(lines[1], ::testing::MatchesRegex("notice: postgresql .* answers again: a statement came back after [0-9.]+ s"));
}

}  // namespace
}  // namespace loopwire::gateway
