// The history reader (gateway/history_reader.hpp) answers queries on its own thread and
// connections: while an ask is held there, a local query the test keeps waiting or a historian
// that accepts the connection and never answers, the store's writer thread goes on committing,
// and what it commits is readable on another connection to the file before the ask is let go.
#include "gateway/history_reader.hpp"

#include <gtest/gtest.h>

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <functional>
#include <future>
#include <memory>
#include <optional>
#include <thread>

#include <fmt/format.h>

#include "gateway/history_store.hpp"
#include "gateway/sqlite_database.hpp"
#include "support/history_parts.hpp"
#include "support/history_test_support.hpp"
#include "support/loopback_listener.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using loopwire::testing::HistoryParts;
using loopwire::testing::HistoryPartsOptions;
using loopwire::testing::LoopbackListener;
using loopwire::testing::TempFolder;

// Generous for a loaded machine: a commit is due every 20 ms here.
constexpr auto deadline = 10s;

ValueChange number(double value, std::chrono::system_clock::time_point sampled) {
    ValueChange change;
    change.device = "oven1";
    change.parameter = "measured_value";
    change.unit = "°C";
    change.status = "ok";
    change.value = device::EngineeringValue{value, "ok", 0, ""};
    change.sampled = sampled;
    return change;
}

HistoryQuery last_minute(const std::string& gateway = "") {
    HistoryQuery query;
    query.device = "oven1";
    query.gateway = gateway;
    query.from = std::chrono::system_clock::now() - 1min;
    query.to = std::chrono::system_clock::now() + 1min;
    query.points = 1;
    return query;
}

// The store's writer and the reader each on their own thread, as the gateway runs them.
std::unique_ptr<HistoryParts> running(HistoryPartsOptions options) {
    options.commit_interval = 20ms;
    options.reader_thread = true;
    auto parts = HistoryParts::open(std::move(options));
    if (!parts) ADD_FAILURE() << parts.error().message;
    if (!parts) return nullptr;
    (*parts)->store->start();
    return std::move(*parts);
}

// The samples another connection to the file sees, once it sees `expected` of them (or the
// deadline passed: the count it saw then).
std::int64_t samples_seen(const std::filesystem::path& file, std::int64_t expected) {
    auto db = sqlite::Connection::open(file.string(), sqlite::Connection::Mode::read_only);
    if (!db) {
        ADD_FAILURE() << db.error().message;
        return -1;
    }
    const auto give_up = std::chrono::steady_clock::now() + deadline;
    for (;;) {
        auto count = db->query_integer("SELECT count(*) FROM samples");
        if (!count) {
            ADD_FAILURE() << count.error().message;
            return -1;
        }
        if (*count >= expected || std::chrono::steady_clock::now() > give_up) return *count;
        std::this_thread::sleep_for(5ms);  // the writer commits on its own clock; look again
    }
}

// Records values 0..n-1, a millisecond apart, stamped now.
void record(HistoryParts& history, int n) {
    const auto now = std::chrono::system_clock::now();
    for (int i = 0; i < n; ++i) history.record(number(i, now - std::chrono::milliseconds(n - i)));
}

TEST(HistoryReader, ALocalQueryHeldOnTheReaderDelaysNoCommit) {
    TempFolder folder;
    HistoryPartsOptions options;
    options.database = folder.path / "plant.db";
    auto history = running(options);
    ASSERT_TRUE(history);

    // An ask the test holds on the reader's thread, and a query queued behind it.
    std::promise<void> started;
    std::promise<void> release;
    std::shared_future<void> released = release.get_future().share();
    history->reader->run_blocking([&started, released] {
        started.set_value();
        released.wait();
    });
    std::promise<Result<std::vector<HistorySeries>>> answer;
    auto answered = answer.get_future();
    const HistoryReader& reader = *history->reader;
    history->reader->run_blocking([&answer, &reader] { answer.set_value(reader.query(last_minute())); });
    ASSERT_EQ(started.get_future().wait_for(deadline), std::future_status::ready) << "the reader never took the held ask";

    record(*history, 50);
    EXPECT_EQ(samples_seen(folder.path / "plant.db", 50), 50) << "the writer did not commit while a query was held";
    EXPECT_EQ(history->rows_written(), 50u);
    EXPECT_EQ(answered.wait_for(0s), std::future_status::timeout) << "the query behind the held ask ran before it";

    release.set_value();
    ASSERT_EQ(answered.wait_for(deadline), std::future_status::ready) << "the query was not answered once let go";
    auto series = answered.get();
    ASSERT_TRUE(series) << series.error().message;
    ASSERT_EQ(series->size(), 1u);
    ASSERT_EQ((*series)[0].buckets.size(), 1u);
    EXPECT_EQ((*series)[0].buckets[0].count, 50u);
    EXPECT_EQ((*series)[0].buckets[0].max, 49);
}

// A historian that takes the connection and says nothing (a host frozen mid-handshake): the
// reader waits for it, the writer does not.
TEST(HistoryReader, AHistorianThatNeverAnswersDelaysNoCommit) {
    TempFolder folder;
    auto listener = std::make_unique<LoopbackListener>();
    HistoryPartsOptions options;
    options.database = folder.path / "north.db";
    ForwardOptions forward;
    // Neither TLS nor GSS asked first: one connection, whose end ends the connect.
    forward.conninfo = fmt::format("host=127.0.0.1 port={} dbname=plant user=loopwire sslmode=disable gssencmode=disable",
                                   listener->port());
    forward.gateway = "north";
    forward.thread = false;  // nothing is forwarded here: only the reader goes to the historian
    options.forward = forward;
    HistorianLimits limits;
    limits.connect_timeout_seconds = 120;  // the test lets the connect go, not the timeout
    options.historian_limits = limits;
    auto history = running(options);
    ASSERT_TRUE(history);

    std::promise<Result<std::vector<HistorySeries>>> answer;
    auto answered = answer.get_future();
    const HistoryReader& reader = *history->reader;
    history->reader->run_blocking([&answer, &reader] { answer.set_value(reader.query(last_minute("south"))); });
    pollfd waiting{listener->fd(), POLLIN, 0};
    ASSERT_EQ(::poll(&waiting, 1, static_cast<int>(std::chrono::milliseconds(deadline).count())), 1)
        << "the reader never connected to the historian";
    const int peer = ::accept(listener->fd(), nullptr, nullptr);
    ASSERT_GE(peer, 0);

    record(*history, 50);
    EXPECT_EQ(samples_seen(folder.path / "north.db", 50), 50) << "the writer did not commit while the historian was silent";
    EXPECT_EQ(answered.wait_for(0s), std::future_status::timeout) << "the historian's query ended before it was let go";

    // Let go: the connection closes, and no other is taken.
    ::close(peer);
    listener.reset();
    ASSERT_EQ(answered.wait_for(deadline), std::future_status::ready) << "the historian's query did not end once let go";
    auto series = answered.get();
    ASSERT_FALSE(series);
    EXPECT_EQ(series.error().kind, ErrorKind::link) << series.error().message;
    // This gateway's own history still comes from the file, on the same reader.
    auto own = history->query(last_minute("north"));
    ASSERT_TRUE(own) << own.error().message;
    ASSERT_EQ(own->size(), 1u);
    EXPECT_EQ((*own)[0].buckets.at(0).count, 50u);
}

// Asked from a thread other than the reader's, a query is handed to the reader and waited for:
// the connection stays the reader thread's alone.
TEST(HistoryReader, AQueryFromAnotherThreadWaitsItsTurnOnTheReader) {
    TempFolder folder;
    HistoryPartsOptions options;
    options.database = folder.path / "plant.db";
    auto history = running(options);
    ASSERT_TRUE(history);
    record(*history, 5);
    ASSERT_EQ(samples_seen(folder.path / "plant.db", 5), 5);

    std::promise<void> started;
    std::promise<void> release;
    std::shared_future<void> released = release.get_future().share();
    history->reader->run_blocking([&started, released] {
        started.set_value();
        released.wait();
    });
    ASSERT_EQ(started.get_future().wait_for(deadline), std::future_status::ready);
    auto asked = std::async(std::launch::async, [&history] { return history->query(last_minute()); });
    EXPECT_EQ(asked.wait_for(50ms), std::future_status::timeout) << "the query ran beside the reader's held ask";
    release.set_value();
    ASSERT_EQ(asked.wait_for(deadline), std::future_status::ready);
    auto series = asked.get();
    ASSERT_TRUE(series) << series.error().message;
    EXPECT_EQ((*series)[0].buckets.at(0).count, 5u);
}

}  // namespace
}  // namespace loopwire::gateway
