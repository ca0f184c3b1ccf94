// The Modbus TCP master: transaction ids, several requests in flight, replies out of order.
#include <gtest/gtest.h>

#include <future>
#include <iostream>
#include <mutex>
#include <thread>

#include "codec/tcp.hpp"
#include "common/never_sent.hpp"
#include "session/line_loop.hpp"
#include "session/master.hpp"
#include "simulation/register_bank.hpp"
#include "session/slave.hpp"
#include "transport/tcp.hpp"
#include "support/thread_names.hpp"

namespace loopwire::session {
namespace {

using namespace std::chrono_literals;

struct Loopback {
    std::unique_ptr<transport::TcpListener> listener;
    transport::LinkUrl link;
};

Loopback listen_on_loopback() {
    auto listener = transport::TcpListener::listen("127.0.0.1", 0);
    EXPECT_TRUE(listener.ok());
    auto link = *transport::parse_link_url("tcp://127.0.0.1:" + std::to_string((*listener)->port()));
    return {std::move(*listener), link};
}

// Reads `count` requests, then answers them in reverse order: each reply carries its request's
// start address as the register value, so a mix-up shows. The connection is handed to
// `connection`, for the test to keep open until the master has read the replies.
void answer_in_reverse(transport::TcpListener& listener, std::size_t count,
                       std::unique_ptr<transport::ByteStream>& connection) {
    auto client = listener.accept(2s);
    ASSERT_TRUE(client.ok() && *client);
    codec::MbapDecoder decoder;
    std::vector<codec::Frame> requests;
    std::array<std::uint8_t, 512> buffer{};
    while (requests.size() < count) {
        auto n = (*client)->read_some(buffer, 2s);
        ASSERT_TRUE(n.ok() && *n > 0);
        auto frames = decoder.feed(ByteView(buffer.data(), *n));
        ASSERT_TRUE(frames.ok());
        requests.insert(requests.end(), frames->begin(), frames->end());
    }
    for (auto it = requests.rbegin(); it != requests.rend(); ++it) {
        auto request = codec::decode_request(it->pdu);
        ASSERT_TRUE(request.ok());
        codec::Reply reply{3, codec::ReplyKind::normal, 0, request->address, 1, {request->address}};
        auto pdu = codec::encode_reply(reply);
        ASSERT_TRUE(pdu.ok());
        ASSERT_TRUE((*client)->write(codec::mbap_encode(it->transaction, it->unit, *pdu)).ok());
    }
    connection = std::move(*client);
}

// A read of holding register 0 of unit 1, sent without waiting: its outcome comes in the future.
std::future<Result<codec::Reply>> read_later(Master& master) {
    auto promise = std::make_shared<std::promise<Result<codec::Reply>>>();
    auto outcome = promise->get_future();
    master.execute_async(1, codec::read_request(codec::FunctionCode::read_holding_registers, 0, 1),
                         [promise](Result<codec::Reply> reply) { promise->set_value(std::move(reply)); });
    return outcome;
}

TEST(TcpMaster, MatchesOutOfOrderRepliesByTransactionId) {
    auto [listener, link] = listen_on_loopback();
    std::unique_ptr<transport::ByteStream> connection;  // open until the test has its replies
    std::thread server([&, l = listener.get()] { answer_in_reverse(*l, 3, connection); });
    auto master = open_master(link, MasterOptions{});
    ASSERT_TRUE(master.ok()) << master.error().message;
    std::vector<std::future<Result<codec::Reply>>> replies;
    for (std::uint16_t address : std::initializer_list<std::uint16_t>{10, 20, 30}) {
        auto promise = std::make_shared<std::promise<Result<codec::Reply>>>();
        replies.push_back(promise->get_future());
        (*master)->execute_async(1, codec::read_request(codec::FunctionCode::read_holding_registers, address, 1),
                                 [promise](Result<codec::Reply> r) { promise->set_value(std::move(r)); });
    }
    std::uint16_t expected = 10;
    for (auto& reply : replies) {
        auto r = reply.get();
        ASSERT_TRUE(r.ok()) << r.error().message;
        EXPECT_EQ(r->values.at(0), expected);
        expected += 10;
    }
    server.join();
}

TEST(TcpMaster, TimesOutWhenTheServerStaysSilent) {
    auto [listener, link] = listen_on_loopback();
    MasterOptions options;
    options.timeout = 100ms;
    options.retries = 1;
    auto master = open_master(link, options);
    ASSERT_TRUE(master.ok());
    auto accepted = listener->accept(1s);  // accepted, never answered
    const auto start = std::chrono::steady_clock::now();
    auto reply = (*master)->execute(1, codec::read_request(codec::FunctionCode::read_holding_registers, 0, 1));
    ASSERT_FALSE(reply.ok());
    EXPECT_EQ(reply.error().kind, ErrorKind::timeout);
    EXPECT_NE(reply.error().message.find("2 tries"), std::string::npos) << reply.error().message;
    EXPECT_GE(std::chrono::steady_clock::now() - start, 200ms);
}

// A gateway that stops or reloads closes its lines' masters: what awaits a reply from a server
// that will not answer ends then, not at its timeout (an hour here), and nothing more is sent.
TEST(TcpMaster, CloseEndsWhatAwaitsItsReplyAndSendsNothingMore) {
    auto [listener, link] = listen_on_loopback();
    MasterOptions options;
    options.timeout = 1h;
    auto master = open_master(link, options);
    ASSERT_TRUE(master.ok());
    auto accepted = listener->accept(10s);
    ASSERT_TRUE(accepted.ok() && *accepted);
    auto ended = read_later(**master);
    std::array<std::uint8_t, 64> buffer{};
    const auto request = (*accepted)->read_some(buffer, 10s);
    ASSERT_TRUE(request.ok() && *request == 12U) << "the request never reached the server";

    (*master)->close();
    ASSERT_EQ(ended.wait_for(30s), std::future_status::ready) << "close() did not end the request awaiting its reply";
    const auto reply = ended.get();
    ASSERT_FALSE(reply.ok());
    EXPECT_TRUE(abandoned(reply.error())) << reply.error().message;

    const auto after = (*master)->execute(1, codec::read_request(codec::FunctionCode::read_holding_registers, 0, 1));
    ASSERT_FALSE(after.ok());
    EXPECT_TRUE(abandoned(after.error())) << after.error().message;
    const auto sent = (*accepted)->read_some(buffer, 100ms);
    EXPECT_TRUE(sent.ok() && *sent == 0U) << "a request was sent after close()";
}

// On a loop shared with other lines (MasterOptions::loop, the gateway's lines' loop) the
// connection is read there: the master has no thread of its own, and its deadlines run on the
// loop's clock. In virtual time a silent server's 60 s timeout passes at once.
TEST(TcpMasterOnALoop, IsReadOnTheLoopAndTimesOutOnItsClock) {
    auto [listener, link] = listen_on_loopback();
    const auto threads_before = loopwire::testing::thread_names().size();
    auto clock = std::make_shared<VirtualClock>();
    auto loop = std::make_shared<LineLoop>(clock);
    MasterOptions options;
    options.timeout = 60s;
    options.loop = loop;
    auto master = open_master(link, options);
    ASSERT_TRUE(master.ok()) << master.error().message;
    EXPECT_EQ(loopwire::testing::thread_names().size(), threads_before + 1) << "the loop's thread and no other";
    auto accepted = listener->accept(10s);  // held open, never answered
    ASSERT_TRUE(accepted.ok() && *accepted);

    const Instant sent_at = clock->now();
    auto ended = read_later(**master);
    ASSERT_EQ(ended.wait_for(30s), std::future_status::ready) << "the 60 s of virtual time never passed";
    const auto reply = ended.get();
    ASSERT_FALSE(reply.ok());
    EXPECT_EQ(reply.error().kind, ErrorKind::timeout) << reply.error().message;
    EXPECT_GE(clock->now() - sent_at, 60s);
}

// Pipelined on the shared loop: replies in reverse order go to their requests. A blocking call
// from the loop's own thread would wait for a reply read by that very thread: refused.
TEST(TcpMasterOnALoop, MatchesRepliesAndRefusesABlockingCallFromTheLoop) {
    auto [listener, link] = listen_on_loopback();
    std::unique_ptr<transport::ByteStream> connection;  // open until the test has its replies
    std::thread server([&, l = listener.get()] { answer_in_reverse(*l, 3, connection); });
    auto loop = std::make_shared<LineLoop>();
    MasterOptions options;
    options.loop = loop;
    auto master = open_master(link, options);
    ASSERT_TRUE(master.ok()) << master.error().message;
    std::vector<std::future<Result<codec::Reply>>> replies;
    std::vector<std::promise<Result<codec::Reply>>> promises(3);
    for (std::uint16_t i = 0; i < 3; ++i) {
        replies.push_back(promises[i].get_future());
        (*master)->execute_async(1, codec::read_request(codec::FunctionCode::read_holding_registers, static_cast<std::uint16_t>(10 * (i + 1)), 1),
                                 [&promises, i](Result<codec::Reply> reply) { promises[i].set_value(std::move(reply)); });
    }
    for (std::uint16_t i = 0; i < 3; ++i) {
        ASSERT_EQ(replies[i].wait_for(30s), std::future_status::ready);
        auto reply = replies[i].get();
        ASSERT_TRUE(reply.ok()) << reply.error().message;
        EXPECT_EQ(reply->values.at(0), 10 * (i + 1));
    }
    server.join();

    std::promise<Result<codec::Reply>> from_loop;
    loop->post([&] { from_loop.set_value((*master)->execute(1, codec::read_request(codec::FunctionCode::read_holding_registers, 0, 1))); });
    auto refused = from_loop.get_future();
    ASSERT_EQ(refused.wait_for(30s), std::future_status::ready) << "a blocking call on the loop's thread hung";
    const auto outcome = refused.get();
    ASSERT_FALSE(outcome.ok());
    EXPECT_EQ(outcome.error().kind, ErrorKind::usage) << outcome.error().message;
}

// On the gateway's loop a lost connection is not made again by the master (a blocking connect
// would hold every line on the loop): requests fail as a link error naming why it was lost, for
// the line's keeper (gateway/reopening_master.hpp) to reopen it. The server sees no second
// connection.
TEST(TcpMasterOnALoop, ALostConnectionIsReportedNotMadeAgain) {
    auto [listener, link] = listen_on_loopback();
    auto loop = std::make_shared<LineLoop>();
    MasterOptions options;
    options.loop = loop;
    options.timeout = 10s;
    auto master = open_master(link, options);
    ASSERT_TRUE(master.ok()) << master.error().message;
    auto accepted = listener->accept(10s);
    ASSERT_TRUE(accepted.ok() && *accepted);
    auto ended = read_later(**master);
    std::array<std::uint8_t, 64> buffer{};
    ASSERT_TRUE((*accepted)->read_some(buffer, 10s).ok());
    accepted->reset();  // the server drops the connection with the request unanswered

    ASSERT_EQ(ended.wait_for(30s), std::future_status::ready) << "the lost connection was not noticed";
    const auto lost = ended.get();
    ASSERT_FALSE(lost.ok());
    EXPECT_EQ(lost.error().kind, ErrorKind::link);
    EXPECT_NE(lost.error().message.find("lost"), std::string::npos) << lost.error().message;

    const auto after = (*master)->execute(1, codec::read_request(codec::FunctionCode::read_holding_registers, 0, 1));
    ASSERT_FALSE(after.ok());
    EXPECT_EQ(after.error().kind, ErrorKind::link);
    EXPECT_NE(after.error().message.find("lost"), std::string::npos) << after.error().message;
    auto again = listener->accept(100ms);
    ASSERT_TRUE(again.ok());
    EXPECT_EQ(*again, nullptr) << "the master connected again by itself";
}

// A device whose TCP stack takes the connection but which stopped reading it: once the kernel's
// buffers are full a request is not waited for (the sender may be the gateway's engine, which
// every front shares): it fails as a link error saying the device is not reading, and so does
// the next, as the loop drops the connection, which may hold part of a frame.
TEST(TcpMasterOnALoop, ADeviceThatStopsReadingFailsTheWriteInsteadOfHoldingTheSender) {
    // The first failure (on this thread, at the write); those awaiting replies fail on the loop,
    // up to the master's end: declared before it, so that they outlive it.
    std::mutex mutex;
    std::optional<Error> refused;
    auto [listener, link] = listen_on_loopback();
    auto loop = std::make_shared<LineLoop>();
    MasterOptions options;
    options.loop = loop;
    options.timeout = 1h;
    auto master = open_master(link, options);
    ASSERT_TRUE(master.ok()) << master.error().message;
    auto accepted = listener->accept(10s);  // never read
    ASSERT_TRUE(accepted.ok() && *accepted);

    // Write multiple registers, 123 of them: 259 bytes a frame. Loopback buffers take some
    // megabytes; far fewer than this many frames fill them.
    const Bytes pdu = [] {
        Bytes bytes{0x10, 0x00, 0x00, 0x00, 123, 246};
        bytes.resize(bytes.size() + 246, 0x55);
        return bytes;
    }();
    const auto first_refusal = [&] {
        std::lock_guard lock(mutex);
        return refused;
    };
    int sent = 0;
    for (; sent < 200000 && !first_refusal(); ++sent) {
        (*master)->forward_async(1, pdu, [&](Result<Bytes> outcome) {
            std::lock_guard lock(mutex);
            if (!outcome && !refused) refused = outcome.error();
        });
    }
    ASSERT_TRUE(first_refusal()) << "200000 frames of 259 bytes all taken by a connection nobody reads";
    EXPECT_EQ(refused->kind, ErrorKind::link);
    EXPECT_NE(refused->message.find("not reading"), std::string::npos) << refused->message;
    EXPECT_NE(refused->message.find("not waited for"), std::string::npos) << "the sender waited for room: " << refused->message;
    std::cout << "the connection took " << sent - 1 << " frames before its buffers were full\n";

    const auto after = (*master)->forward(1, pdu);
    ASSERT_FALSE(after.ok());
    EXPECT_EQ(after.error().kind, ErrorKind::link);
    EXPECT_NE(after.error().message.find("lost"), std::string::npos) << after.error().message;
}

TEST(TcpMaster, RefusedConnectionIsALinkError) {
    auto [listener, link] = listen_on_loopback();
    listener.reset();  // nobody listens there any more
    auto master = open_master(link, MasterOptions{});
    ASSERT_FALSE(master.ok());
    EXPECT_EQ(master.error().kind, ErrorKind::link);
}

TEST(TcpMaster, TalksToTheTcpSlaveFromManyThreads) {
    auto [listener, link] = listen_on_loopback();
    auto bank = std::make_shared<RegisterBank>();
    Slave slave(link, {{1, bank}});
    std::jthread server([&, l = listener.get()](std::stop_token stop) { (void)slave.serve_listener(*l, stop); });
    auto master = open_master(link, MasterOptions{});
    ASSERT_TRUE(master.ok());
    std::vector<std::thread> threads;
    std::atomic<int> good{0};
    for (std::uint16_t t = 0; t < 4; ++t) {
        threads.emplace_back([&, t] {
            for (std::uint16_t i = 0; i < 25; ++i) {
                const auto address = static_cast<std::uint16_t>(t * 100 + i);
                if (!(*master)->execute(1, codec::write_single_register(address, address)).ok()) continue;
                auto back = (*master)->execute(1, codec::read_request(codec::FunctionCode::read_holding_registers, address, 1));
                if (back.ok() && back->values.at(0) == address) ++good;
            }
        });
    }
    for (auto& t : threads) t.join();
    EXPECT_EQ(good.load(), 100);
}

TEST(TcpMaster, UnitFFReachesTheOnlyServedUnit) {
    auto [listener, link] = listen_on_loopback();
    auto bank = std::make_shared<RegisterBank>();
    bank->set(Table::holding_registers, 4, 44);
    Slave slave(link, {{1, bank}});
    std::jthread server([&, l = listener.get()](std::stop_token stop) { (void)slave.serve_listener(*l, stop); });
    auto master = open_master(link, MasterOptions{});
    ASSERT_TRUE(master.ok());
    auto reply = (*master)->execute(0xFF, codec::read_request(codec::FunctionCode::read_holding_registers, 4, 1));
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(reply->values.at(0), 44);
}

TEST(TcpMaster, UnservedUnitGetsGatewayTargetException) {
    auto [listener, link] = listen_on_loopback();
    Slave slave(link, {{1, std::make_shared<RegisterBank>()}});
    std::jthread server([&, l = listener.get()](std::stop_token stop) { (void)slave.serve_listener(*l, stop); });
    auto master = open_master(link, MasterOptions{});
    ASSERT_TRUE(master.ok());
    auto reply = (*master)->execute(9, codec::read_request(codec::FunctionCode::read_holding_registers, 0, 1));
    ASSERT_FALSE(reply.ok());
    EXPECT_EQ(reply.error().kind, ErrorKind::exception);
    EXPECT_EQ(reply.error().code, 0x0B);
}

}  // namespace
}  // namespace loopwire::session

namespace loopwire::session {
namespace {

// A server that restarts: the master reports the lost connection, then connects again on the
// next request instead of staying broken.
TEST(TcpMaster, ReconnectsAfterTheServerRestarts) {
    auto [listener, link] = listen_on_loopback();
    const auto read = codec::read_request(codec::FunctionCode::read_holding_registers, 0, 1);
    MasterOptions options;
    options.timeout = 500ms;
    auto master = open_master(link, options);
    ASSERT_TRUE(master.ok());
    {
        Slave slave(link, {{1, std::make_shared<RegisterBank>()}});
        std::jthread server([&, l = listener.get()](std::stop_token stop) { (void)slave.serve_listener(*l, stop); });
        ASSERT_TRUE((*master)->execute(1, read).ok());
    }  // the server stops and its connections close
    listener.reset();
    auto again = transport::TcpListener::listen("127.0.0.1", link.port);
    ASSERT_TRUE(again.ok()) << again.error().message;
    auto bank = std::make_shared<RegisterBank>();
    bank->set(Table::holding_registers, 0, 7);
    Slave slave(link, {{1, bank}});
    std::jthread server([&, l = again->get()](std::stop_token stop) { (void)slave.serve_listener(*l, stop); });
    Result<codec::Reply> reply = make_error(ErrorKind::link, "not tried");
    for (int attempt = 0; attempt < 3 && !reply.ok(); ++attempt) {
        reply = (*master)->execute(1, read);
        if (!reply.ok()) {
            EXPECT_EQ(reply.error().kind, ErrorKind::link) << reply.error().message;
        }
    }
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(reply->values.at(0), 7);
}

}  // namespace
}  // namespace loopwire::session
