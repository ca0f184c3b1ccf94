// The gateway's event loop (gateway/engine.hpp): requests its handlers send to a pipelined
// Modbus TCP line in one round reach the device in one write.
#include <gtest/gtest.h>

#include <future>

#include <boost/asio/post.hpp>

#include "gateway/engine.hpp"
#include "session/master.hpp"
#include "support/request_counting_server.hpp"
#include "transport/tcp.hpp"

namespace loopwire::gateway {
namespace {

TEST(Engine, RequestsSentInOneRoundToATcpLineGoOutInOneWrite) {
    auto listener = transport::TcpListener::listen("127.0.0.1", 0);
    ASSERT_TRUE(listener.ok());
    const auto link = *transport::parse_link_url("tcp://127.0.0.1:" + std::to_string((*listener)->port()));
    constexpr std::size_t requests = 6;
    auto served = std::async(std::launch::async, [&] { return testing::serve_requests(**listener, requests); });
    auto master = session::open_master(link, session::MasterOptions{});
    ASSERT_TRUE(master.ok()) << master.error().message;
    testing::RoundOfReads round(200, requests);
    Engine engine;
    boost::asio::post(engine.loop(), round.sender(**master));
    const auto served_requests = served.get();
    const auto& reads = served_requests.reads;
    ASSERT_FALSE(reads.empty());
    EXPECT_EQ(reads.front(), requests * 12) << "the device's first read brought only part of the round's requests";
    round.expect_answered();
}

}  // namespace
}  // namespace loopwire::gateway
