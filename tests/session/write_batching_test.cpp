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

// A server that reads until it has `count` requests, noting how many bytes each read brought,
// then answers each with its start address as the value.
std::vector<std::size_t> serve_requests(transport::TcpListener& listener, std::size_t count) {
    std::vector<std::size_t> reads;
    auto client = listener.accept(5s);
    if (!client.ok() || !*client) return reads;
    codec::MbapDecoder decoder;
    std::vector<codec::Frame> requests;
    std::array<std::uint8_t, 1024> buffer{};
    while (requests.size() < count) {
        auto n = (*client)->read_some(buffer, 5s);
        if (!n.ok() || *n == 0) return reads;
        reads.push_back(*n);
        auto frames = decoder.feed(ByteView(buffer.data(), *n));
        if (!frames.ok()) return reads;
        requests.insert(requests.end(), frames->begin(), frames->end());
    }
    Bytes replies;
    for (const auto& request : requests) {
        auto decoded = codec::decode_request(request.pdu);
        if (!decoded.ok()) return reads;
        auto pdu = codec::encode_reply({3, codec::ReplyKind::normal, 0, decoded->address, 1, {decoded->address}});
        const Bytes frame = codec::mbap_encode(request.transaction, request.unit, *pdu);
        replies.insert(replies.end(), frame.begin(), frame.end());
    }
    (void)(*client)->write(replies);
    std::this_thread::sleep_for(200ms);  // keep the connection until the master has read
    return reads;
}

TEST(WriteBatching, ATcpMastersRequestsOfOneRoundGoOutInOneWrite) {
    auto listener = transport::TcpListener::listen("127.0.0.1", 0);
    ASSERT_TRUE(listener.ok());
    const auto link = *transport::parse_link_url("tcp://127.0.0.1:" + std::to_string((*listener)->port()));
    constexpr std::size_t requests = 8;
    auto served = std::async(std::launch::async, [&] { return serve_requests(**listener, requests); });
    auto master = open_master(link, MasterOptions{});
    ASSERT_TRUE(master.ok()) << master.error().message;

    asio::io_context loop;
    WriteBatching::Scope scope(post_on(loop));
    std::vector<std::promise<Result<codec::Reply>>> replies(requests);
    asio::post(loop, [&] {
        for (std::size_t i = 0; i < requests; ++i) {
            const auto address = static_cast<std::uint16_t>(100 + i);
            (*master)->execute_async(1, codec::read_request(codec::FunctionCode::read_holding_registers, address, 1),
                                     [&replies, i](Result<codec::Reply> reply) { replies[i].set_value(std::move(reply)); });
        }
    });
    loop.run();

    const auto reads = served.get();
    ASSERT_FALSE(reads.empty());
    EXPECT_EQ(reads.front(), requests * 12) << "the server's first read brought only part of the round's requests";
    for (std::size_t i = 0; i < requests; ++i) {
        auto reply = replies[i].get_future().get();
        ASSERT_TRUE(reply.ok()) << reply.error().message;
        EXPECT_EQ(reply->values.at(0), 100 + i);
    }
}

}  // namespace
}  // namespace loopwire::session
