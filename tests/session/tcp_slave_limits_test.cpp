// The TCP slave's limits on what its clients may hold (TcpClientLimits): connections at once,
// idle time, requests in progress per connection; and the flag that tells a deferring handler
// (a gateway's line) that a request's connection has gone. Real sockets on 127.0.0.1.
#include <gtest/gtest.h>

#include <sys/socket.h>

#include <algorithm>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <vector>

#include "support/eventually.hpp"
#include "support/test_bytes.hpp"
#include "tcp_test_client.hpp"

namespace loopwire::session {
namespace {

using loopwire::testing::eventually;
using loopwire::testing::hex;
using testing::RawClient;
using testing::ServedSlave;
using namespace std::chrono_literals;

// Generous: these only bound how long a failing test takes on a loaded machine.
constexpr auto patience = 30s;

// Holds every request until the test answers it, and keeps each one's asker.
class HoldingUnit final : public UnitHandler {
public:
    struct Held {
        Bytes pdu;
        Asker asker;
        ReplyCallback reply;
    };

    std::optional<Bytes> handle(ByteView, bool) override { return std::nullopt; }
    void handle_async(Bytes request_pdu, bool, const Asker& asker, ReplyCallback reply) override {
        std::lock_guard lock(mutex_);
        held_.push_back({std::move(request_pdu), asker, std::move(reply)});
        ++arrived_;
        changed_.notify_all();
    }

    // Waits until `count` requests have arrived in all (a test failure after `patience`).
    bool wait_for_arrivals(std::size_t count) {
        std::unique_lock lock(mutex_);
        const bool came = changed_.wait_for(lock, patience, [&] { return arrived_ >= count; });
        EXPECT_TRUE(came) << arrived_ << " of " << count << " requests reached the handler";
        return came;
    }
    std::size_t arrived() {
        std::lock_guard lock(mutex_);
        return arrived_;
    }
    // Answers the oldest request still held with a one-register read reply of `value`.
    void answer_oldest(std::uint8_t value) {
        Held oldest;
        {
            std::lock_guard lock(mutex_);
            ASSERT_FALSE(held_.empty()) << "no request held";
            oldest = std::move(held_.front());
            held_.erase(held_.begin());
        }
        oldest.reply(Bytes{0x03, 0x02, 0x00, value});
    }
    std::vector<Asker> askers() {
        std::lock_guard lock(mutex_);
        std::vector<Asker> all;
        for (const auto& held : held_) all.push_back(held.asker);
        return all;
    }
    // Answers what is still held, so nothing is left owed when the server stops.
    void answer_all() {
        while (!empty()) answer_oldest(0);
    }

private:
    bool empty() {
        std::lock_guard lock(mutex_);
        return held_.empty();
    }

    std::mutex mutex_;
    std::condition_variable changed_;
    std::vector<Held> held_;
    std::size_t arrived_ = 0;
};

SlaveOptions with_limits(std::size_t max_connections, std::chrono::milliseconds idle_timeout = 0ms,
                         std::size_t max_outstanding = 32) {
    SlaveOptions options;
    options.tcp.max_connections = max_connections;
    options.tcp.idle_timeout = idle_timeout;
    options.tcp.max_outstanding_requests = max_outstanding;
    return options;
}

// A read answered, so the client has been served and its connection is known to the server.
void served_once(RawClient& client, std::uint16_t transaction) {
    ASSERT_TRUE(client.send(testing::read_one_register(transaction, 0)));
    EXPECT_EQ(client.receive(11, 10000ms).size(), 11u);
}

// Three clients each served once, oldest first; a fourth is admitted by closing the one idle
// longest, and the other three are served.
TEST(TcpSlaveLimits, AtMaxConnectionsTheLongestIdleIsClosedToAdmitANewClient) {
    ServedSlave served(UnitMap{{1, std::make_shared<RegisterBank>()}}, "tcp://127.0.0.1:0", with_limits(3));
    RawClient first(served.port());
    served_once(first, 1);
    RawClient second(served.port());
    served_once(second, 1);
    RawClient third(served.port());
    served_once(third, 1);
    RawClient fourth(served.port());
    served_once(fourth, 1);
    EXPECT_TRUE(first.closed_by_server_within(patience)) << "the longest idle connection stayed open";
    served_once(second, 2);
    served_once(third, 2);
    served_once(fourth, 2);
    const auto statistics = served.slave().tcp_statistics();
    EXPECT_EQ(statistics.accepted, 4u);
    EXPECT_EQ(statistics.evicted, 1u);
    EXPECT_EQ(statistics.open, 3u);
}

// A socket opened and left without a whole request goes before a client that has been served,
// even one idle for longer: idle sockets never push out a working client.
TEST(TcpSlaveLimits, ASocketThatNeverSentARequestGoesBeforeAServedClient) {
    ServedSlave served(UnitMap{{1, std::make_shared<RegisterBank>()}}, "tcp://127.0.0.1:0", with_limits(2));
    RawClient working(served.port());
    served_once(working, 1);
    RawClient silent(served.port());
    ASSERT_TRUE(silent.send(Bytes{0x00, 0x01, 0x00}));  // half a header, never finished
    ASSERT_TRUE(eventually([&] { return served.slave().tcp_statistics().open == 2; }));
    RawClient newcomer(served.port());
    served_once(newcomer, 1);
    EXPECT_TRUE(silent.closed_by_server_within(patience));
    served_once(working, 2);
    EXPECT_EQ(served.slave().tcp_statistics().evicted, 1u);
}

// When every connection has a request in progress, each of them is a client being served: the
// newcomer is closed instead, and the others get their replies.
TEST(TcpSlaveLimits, WhenEveryConnectionIsBusyTheNewcomerIsRefused) {
    auto unit = std::make_shared<HoldingUnit>();
    ServedSlave served(UnitMap{{1, unit}}, "tcp://127.0.0.1:0", with_limits(2));
    RawClient first(served.port());
    RawClient second(served.port());
    ASSERT_TRUE(first.send(testing::read_one_register(1, 0)));
    ASSERT_TRUE(unit->wait_for_arrivals(1));
    ASSERT_TRUE(second.send(testing::read_one_register(1, 0)));
    ASSERT_TRUE(unit->wait_for_arrivals(2));
    RawClient newcomer(served.port());
    EXPECT_TRUE(newcomer.closed_by_server_within(patience));
    unit->answer_oldest(1);
    unit->answer_oldest(2);
    EXPECT_EQ(first.receive(11, 10000ms), hex("00 01 00 00 00 05 01 03 02 00 01"));
    EXPECT_EQ(second.receive(11, 10000ms), hex("00 01 00 00 00 05 01 03 02 00 02"));
    const auto statistics = served.slave().tcp_statistics();
    EXPECT_EQ(statistics.refused, 1u);
    EXPECT_EQ(statistics.evicted, 0u);
}

// A connection quiet for idle_timeout is closed; one whose request is still in progress is not
// idle, however long the handler takes, and gets its reply.
TEST(TcpSlaveLimits, AConnectionIdleLongerThanTheIdleTimeoutIsClosed) {
    auto unit = std::make_shared<HoldingUnit>();
    ServedSlave served(UnitMap{{1, unit}}, "tcp://127.0.0.1:0", with_limits(0, 300ms));
    RawClient waiting(served.port());
    ASSERT_TRUE(waiting.send(testing::read_one_register(1, 0)));
    ASSERT_TRUE(unit->wait_for_arrivals(1));
    // Connected after the other's request arrived: by the time it is closed as idle, the other
    // has been waiting for its reply longer than the idle timeout.
    RawClient idle(served.port());
    EXPECT_TRUE(idle.closed_by_server_within(patience)) << "an idle connection stayed open";
    EXPECT_EQ(served.slave().tcp_statistics().idle_closed, 1u);
    unit->answer_oldest(7);
    EXPECT_EQ(waiting.receive(11, 10000ms), hex("00 01 00 00 00 05 01 03 02 00 07"))
        << "the connection waiting for its reply was closed as idle";
    // Idle in its turn once answered.
    EXPECT_TRUE(waiting.closed_by_server_within(patience));
    EXPECT_EQ(served.slave().tcp_statistics().idle_closed, 2u);
}

// A client pipelining ten requests at once with room for four in progress: the handler gets
// four, then one more for each reply, never the whole burst; all ten are answered in the end.
TEST(TcpSlaveLimits, APipeliningClientHasAtMostTheBoundInProgress) {
    auto unit = std::make_shared<HoldingUnit>();
    ServedSlave served(UnitMap{{1, unit}}, "tcp://127.0.0.1:0", with_limits(0, 0ms, 4));
    RawClient client(served.port());
    Bytes burst;
    for (std::uint16_t transaction = 1; transaction <= 10; ++transaction) {
        const Bytes one = testing::read_one_register(transaction, 0);
        burst.insert(burst.end(), one.begin(), one.end());
    }
    ASSERT_TRUE(client.send(burst));
    ASSERT_TRUE(unit->wait_for_arrivals(4));
    unit->answer_oldest(1);
    ASSERT_TRUE(unit->wait_for_arrivals(5));
    // The rest of the burst was read with the first four: had it been passed on, it would have
    // reached the handler before the first reply was even given.
    EXPECT_EQ(unit->arrived(), 5u) << "requests past the bound reached the handler";
    for (std::uint8_t value = 2; value <= 10; ++value) {
        ASSERT_TRUE(unit->wait_for_arrivals(std::min<std::size_t>(static_cast<std::size_t>(value) + 3, 10)));
        unit->answer_oldest(value);
    }
    const Bytes replies = client.receive(110, 10000ms);
    ASSERT_EQ(replies.size(), 110u);
    for (std::size_t i = 0; i < 10; ++i) {
        EXPECT_EQ(read_be16(replies, i * 11), i + 1) << "reply " << i;  // transaction ids, in order
        EXPECT_EQ(replies[i * 11 + 10], i + 1) << "reply " << i;
    }
}

// The asker a handler is given stops wanting the answer once the client has gone: a reset
// connection, or one whose client has ended its side (what a connect-send-close client does).
TEST(TcpSlaveLimits, TheAskerStopsWantingTheReplyWhenTheClientGoes) {
    auto unit = std::make_shared<HoldingUnit>();
    ServedSlave served(UnitMap{{1, unit}});
    RawClient stays(served.port());
    auto resets = std::make_unique<RawClient>(served.port());
    RawClient ends(served.port());
    ASSERT_TRUE(stays.send(testing::read_one_register(1, 0)));
    ASSERT_TRUE(unit->wait_for_arrivals(1));
    ASSERT_TRUE(resets->send(testing::read_one_register(1, 0)));
    ASSERT_TRUE(unit->wait_for_arrivals(2));
    ASSERT_TRUE(ends.send(testing::read_one_register(1, 0)));
    ASSERT_TRUE(unit->wait_for_arrivals(3));
    const auto askers = unit->askers();
    ASSERT_EQ(askers.size(), 3u);
    for (const auto& asker : askers) ASSERT_TRUE(asker.still_wanted && asker.wanted());
    const linger abort_on_close{1, 0};  // close() sends RST: the connection is simply gone
    ASSERT_EQ(::setsockopt(resets->fd(), SOL_SOCKET, SO_LINGER, &abort_on_close, sizeof abort_on_close), 0);
    resets.reset();
    ::shutdown(ends.fd(), SHUT_WR);  // FIN: the client's side has ended
    EXPECT_TRUE(eventually([&] { return !askers[1].wanted(); })) << "a reset connection still wants its reply";
    EXPECT_TRUE(eventually([&] { return !askers[2].wanted(); })) << "an ended connection still wants its reply";
    EXPECT_TRUE(askers[0].wanted());
    unit->answer_all();
    EXPECT_EQ(stays.receive(11, 10000ms).size(), 11u);
}

}  // namespace
}  // namespace loopwire::session
