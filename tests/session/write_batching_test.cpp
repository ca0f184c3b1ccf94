// Writes put off to the end of a loop's round (session/write_batching.hpp), and the Modbus TCP
// master that uses them: requests a Modbus TCP front forwards in one round reach the device in
// one write.
#include <gtest/gtest.h>

#include <future>
#include <string>
#include <thread>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>

#include "codec/tcp.hpp"
#include "session/master.hpp"
#include "session/write_batching.hpp"
#include "support/request_counting_server.hpp"
#include "transport/tcp.hpp"

namespace loopwire::session {
namespace {

using namespace std::chrono_literals;
namespace asio = boost::asio;

WriteBatching::Post post_on(asio::io_context& loop) {
    return [&loop](std::function<void()> work) { asio::post(loop, std::move(work)); };
}

TEST(WriteBatching, OutsideALoopNothingIsDeferred) {
    bool ran = false;
    EXPECT_FALSE(WriteBatching::defer([&] { ran = true; }));
    EXPECT_FALSE(ran);
}

TEST(WriteBatching, FlushesRunOnceAtTheEndOfTheRoundAfterWhatWasReady) {
    asio::io_context loop;
    std::vector<std::string> order;
    WriteBatching::Scope scope(post_on(loop));
    asio::post(loop, [&] {
        order.push_back("first handler");
        EXPECT_TRUE(WriteBatching::defer([&] { order.push_back("flush a"); }));
        EXPECT_TRUE(WriteBatching::defer([&] { order.push_back("flush b"); }));
    });
    asio::post(loop, [&] { order.push_back("second handler"); });
    loop.run();
    EXPECT_EQ(order, (std::vector<std::string>{"first handler", "second handler", "flush a", "flush b"}));
    // The next round defers again.
    loop.restart();
    asio::post(loop, [&] { EXPECT_TRUE(WriteBatching::defer([&] { order.push_back("flush c"); })); });
    loop.run();
    EXPECT_EQ(order.back(), "flush c");
}

TEST(WriteBatching, ATcpMastersRequestsOfOneRoundGoOutInOneWrite) {
    auto listener = transport::TcpListener::listen("127.0.0.1", 0);
    ASSERT_TRUE(listener.ok());
    const auto link = *transport::parse_link_url("tcp://127.0.0.1:" + std::to_string((*listener)->port()));
    constexpr std::size_t requests = 8;
    auto served = std::async(std::launch::async, [&] { return testing::serve_requests(**listener, requests); });
    auto master = open_master(link, MasterOptions{});
    ASSERT_TRUE(master.ok()) << master.error().message;

    asio::io_context loop;
    WriteBatching::Scope scope(post_on(loop));
    testing::RoundOfReads round(100, requests);
    asio::post(loop, round.sender(**master));
    loop.run();

    const auto served_requests = served.get();
    const auto& reads = served_requests.reads;
    ASSERT_FALSE(reads.empty());
    EXPECT_EQ(reads.front(), requests * 12) << "the server's first read brought only part of the round's requests";
    round.expect_answered();
}

}  // namespace
}  // namespace loopwire::session
