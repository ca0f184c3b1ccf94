// The TCP slave through real loopback sockets: hostile input on one connection (Modbus Messaging
// on TCP/IP Implementation Guide V1.0b; Modbus Application Protocol V1.1b3), deferred replies,
// rtu+tcp silence, stopping, and an idle server that costs no CPU.
#include <gtest/gtest.h>

#include <atomic>

#include <sys/resource.h>
#include <time.h>

#include <condition_variable>
#include <future>
#include <mutex>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>

#include "codec/rtu.hpp"
#include "support/test_bytes.hpp"
#include "tcp_test_client.hpp"

namespace loopwire::session {
namespace {

using loopwire::testing::concat;
using loopwire::testing::hex;
using testing::RawClient;
using testing::ServedSlave;
using namespace std::chrono_literals;

class TcpSlaveWire : public ::testing::Test {
protected:
    std::shared_ptr<RegisterBank> bank = std::make_shared<RegisterBank>();
    ServedSlave served{UnitMap{{1, bank}}};
};

// A valid FC6 write and, in the same segment, a header with protocol id 0001h: the write is
// executed and answered, then the connection is closed (the stream cannot be followed).
TEST_F(TcpSlaveWire, FramesBeforeABadHeaderAreExecutedAndAnsweredThenTheConnectionCloses) {
    RawClient client(served.port());
    const Bytes write = hex("00 07 00 00 00 06 01 06 00 10 12 34");
    ASSERT_TRUE(client.send(concat({write, hex("00 08 00 01 00 06 01 03 00 00 00 01")})));
    EXPECT_EQ(client.receive(write.size()), write);  // FC6 replies echo the request
    EXPECT_EQ(bank->get(Table::holding_registers, 0x10), 0x1234);
    EXPECT_TRUE(client.closed_by_server_within(2000ms));
}

// Function code 0 does not exist and 128 is an exception code: both are unsupported functions,
// answered with exception 1 at once instead of leaving the client to its timeout.
TEST_F(TcpSlaveWire, FunctionCodesZeroAnd128GetIllegalFunction) {
    RawClient client(served.port());
    ASSERT_TRUE(client.send(hex("00 01 00 00 00 02 01 00")));
    EXPECT_EQ(client.receive(9), hex("00 01 00 00 00 03 01 80 01"));
    ASSERT_TRUE(client.send(hex("00 02 00 00 00 04 01 80 00 00")));
    EXPECT_EQ(client.receive(9), hex("00 02 00 00 00 03 01 80 01"));
}

// FC16 with 124 registers (one past the 123 of application protocol 6.12): MBAP length 255. The
// length still delimits the frame, so it is skipped and refused with exception 3, nothing is
// written, and the next request on the same connection is answered.
TEST_F(TcpSlaveWire, OverlongWriteWithAnIntactLengthGetsIllegalDataValueAndTheConnectionStays) {
    Bytes pdu = hex("10 00 00 00 7C F8");
    pdu.resize(pdu.size() + 248, 0x11);
    Bytes request = hex("00 09 00 00 00 FF 01");
    request.insert(request.end(), pdu.begin(), pdu.end());
    ASSERT_EQ(request.size(), 6u + 255u);
    RawClient client(served.port());
    ASSERT_TRUE(client.send(concat({request, testing::read_one_register(10, 0)})));
    EXPECT_EQ(client.receive(9), hex("00 09 00 00 00 03 01 90 03"));
    EXPECT_EQ(client.receive(11), hex("00 0A 00 00 00 05 01 03 02 00 00"));
    EXPECT_EQ(bank->get(Table::holding_registers, 0), 0);
}

// Past 260 the length cannot be trusted to find the next frame: the connection is closed.
TEST_F(TcpSlaveWire, ImpossibleLengthClosesTheConnection) {
    RawClient client(served.port());
    ASSERT_TRUE(client.send(hex("00 01 00 00 01 05 01 03")));
    EXPECT_TRUE(client.closed_by_server_within(2000ms));
}

// Unit 0 is the serial line's broadcast, which only writes and which nobody answers (serial line
// V1.02, 2.1): a read asked of it gets exception 1 at once instead of a reply that never comes,
// while a broadcast write is executed by every unit and, as on the line, not answered (the read
// after it shows both that it was done and that nothing was sent for it).
TEST_F(TcpSlaveWire, UnitZeroReadsGetIllegalFunctionAndBroadcastWritesAreDoneUnanswered) {
    RawClient client(served.port());
    ASSERT_TRUE(client.send(hex("00 01 00 00 00 06 00 03 00 00 00 01")));
    EXPECT_EQ(client.receive(9), hex("00 01 00 00 00 03 00 83 01"));
    ASSERT_TRUE(client.send(hex("00 02 00 00 00 06 00 06 00 05 12 34")));
    ASSERT_TRUE(client.send(testing::read_one_register(3, 5)));
    EXPECT_EQ(client.receive(11), hex("00 03 00 00 00 05 01 03 02 12 34"));
    EXPECT_EQ(bank->get(Table::holding_registers, 5), 0x1234);
}

TEST_F(TcpSlaveWire, PipelinedRequestsAreAllAnsweredInOrder) {
    RawClient client(served.port());
    Bytes requests;
    for (std::uint16_t id = 1; id <= 50; ++id) {
        const Bytes one = testing::read_one_register(id, id);
        requests.insert(requests.end(), one.begin(), one.end());
    }
    ASSERT_TRUE(client.send(requests));
    const Bytes replies = client.receive(50 * 11);
    ASSERT_EQ(replies.size(), 50u * 11u);
    for (std::uint16_t id = 1; id <= 50; ++id) EXPECT_EQ(read_be16(replies, (id - 1u) * 11u), id);
}

TEST(TcpSlaveRtuOverTcp, AFrameOfUnknownLengthIsAnsweredAfterTheSilence) {
    ServedSlave served(UnitMap{{1, std::make_shared<RegisterBank>()}}, "rtu+tcp://127.0.0.1:0");
    RawClient client(served.port());
    // Function 41h gives no length: only the silence after it ends the frame (serial line
    // V1.02, 2.5.1.1), which the server's timer has to notice without further bytes.
    const Bytes request = codec::rtu_encode(1, hex("41 00 01"));
    ASSERT_TRUE(client.send(request));
    EXPECT_EQ(client.receive(5), codec::rtu_encode(1, hex("C1 01")));
    // A frame known by its length is answered too.
    ASSERT_TRUE(client.send(codec::rtu_encode(1, hex("03 00 00 00 01"))));
    EXPECT_EQ(client.receive(7), codec::rtu_encode(1, hex("03 02 00 00")));
}

// A unit handler that answers later, from another thread, in the order the test chooses.
class DeferringUnit final : public UnitHandler {
public:
    std::optional<Bytes> handle(ByteView, bool) override { return std::nullopt; }
    void handle_async(Bytes request_pdu, bool, const Asker&, ReplyCallback reply) override {
        std::lock_guard lock(mutex_);
        pending_.push_back({std::move(request_pdu), std::move(reply)});
        arrived_.notify_all();
    }
    // The requests held so far, once `count` have arrived (or a test failure after 2 s).
    std::vector<std::pair<Bytes, ReplyCallback>> take(std::size_t count) {
        std::unique_lock lock(mutex_);
        EXPECT_TRUE(arrived_.wait_for(lock, 2s, [&] { return pending_.size() >= count; }))
            << pending_.size() << " of " << count << " requests reached the handler";
        return std::exchange(pending_, {});
    }

private:
    std::mutex mutex_;
    std::condition_variable arrived_;
    std::vector<std::pair<Bytes, ReplyCallback>> pending_;
};

// Records who asked: a gateway shares a line fairly between connections by this.
class OriginRecorder final : public UnitHandler {
public:
    std::optional<Bytes> handle(ByteView, bool) override { return Bytes{0x03, 0x02, 0x00, 0x00}; }
    void handle_async(Bytes request_pdu, bool broadcast, const Asker& asker, ReplyCallback reply) override {
        {
            std::lock_guard lock(mutex_);
            origins_.push_back(asker.origin);
        }
        reply(handle(request_pdu, broadcast));
    }
    std::vector<Origin> origins() {
        std::lock_guard lock(mutex_);
        return origins_;
    }

private:
    std::mutex mutex_;
    std::vector<Origin> origins_;
};

TEST(TcpSlaveDeferred, EachConnectionIsOneOriginToTheHandlers) {
    auto recorder = std::make_shared<OriginRecorder>();
    ServedSlave served(UnitMap{{1, recorder}});
    RawClient first(served.port());
    RawClient second(served.port());
    for (std::uint16_t transaction = 1; transaction <= 2; ++transaction) {
        ASSERT_TRUE(first.send(testing::read_one_register(transaction, 0)));
        EXPECT_EQ(first.receive(11).size(), 11u);
        ASSERT_TRUE(second.send(testing::read_one_register(transaction, 0)));
        EXPECT_EQ(second.receive(11).size(), 11u);
    }
    const auto origins = recorder->origins();
    ASSERT_EQ(origins.size(), 4u);
    EXPECT_NE(origins[0], 0u) << "origin 0 is a serial line's";
    EXPECT_EQ(origins[0], origins[2]) << "one connection, one origin";
    EXPECT_EQ(origins[1], origins[3]);
    EXPECT_NE(origins[0], origins[1]) << "two connections share an origin";
}

TEST(TcpSlaveDeferred, RepliesGoOutWhenTheHandlerAnswersFromAnotherThreadInAnyOrder) {
    auto unit = std::make_shared<DeferringUnit>();
    ServedSlave served(UnitMap{{1, unit}});
    RawClient client(served.port());
    ASSERT_TRUE(client.send(concat({testing::read_one_register(1, 5), testing::read_one_register(2, 6)})));
    auto held = unit->take(2);
    ASSERT_EQ(held.size(), 2u);
    std::thread answerer([&] {
        held[1].second(hex("03 02 00 06"));
        held[0].second(hex("03 02 00 05"));
    });
    answerer.join();
    EXPECT_EQ(client.receive(22), concat({hex("00 02 00 00 00 05 01 03 02 00 06"), hex("00 01 00 00 00 05 01 03 02 00 05")}));
}

TEST(TcpSlaveDeferred, SilenceFromADeferringHandlerSendsNothingAndTheNextReplyStillComes) {
    auto unit = std::make_shared<DeferringUnit>();
    ServedSlave served(UnitMap{{1, unit}});
    RawClient client(served.port());
    ASSERT_TRUE(client.send(testing::read_one_register(1, 0)));
    unit->take(1)[0].second(std::nullopt);
    ASSERT_TRUE(client.send(testing::read_one_register(2, 0)));
    unit->take(1)[0].second(hex("03 02 00 00"));
    EXPECT_EQ(client.receive(11), hex("00 02 00 00 00 05 01 03 02 00 00"));
}

// A gateway may answer after the server has gone: the reply is dropped, nothing breaks.
TEST(TcpSlaveDeferred, AReplyAfterTheServerStoppedIsDropped) {
    auto unit = std::make_shared<DeferringUnit>();
    std::vector<std::pair<Bytes, UnitHandler::ReplyCallback>> held;
    {
        ServedSlave served(UnitMap{{1, unit}});
        RawClient client(served.port());
        ASSERT_TRUE(client.send(testing::read_one_register(1, 0)));
        held = unit->take(1);
        served.stop();
        EXPECT_TRUE(served.served_ok());
    }
    ASSERT_EQ(held.size(), 1u);
    std::thread late([&] { held[0].second(hex("03 02 00 00")); });
    late.join();
}

// A gateway stopping (SIGTERM) still answers what it took: a reply on its way from a slow
// handler when stop is requested reaches the client, then the connection closes.
TEST(TcpSlaveDeferred, AReplyOwedWhenStopIsRequestedStillReachesTheClient) {
    auto unit = std::make_shared<DeferringUnit>();
    Slave slave(*transport::parse_link_url("tcp://127.0.0.1:0"), UnitMap{{1, unit}});
    auto listener = transport::TcpListener::listen("127.0.0.1", 0);
    ASSERT_TRUE(listener) << listener.error().message;
    // The server on a loop of the test's, so the test can see when the stop has reached it.
    boost::asio::io_context loop;
    Result<void> served;
    std::atomic<bool> stopped{false};
    std::jthread server([&](std::stop_token stop) {
        served = slave.serve_listener(**listener, std::move(stop), loop);
        stopped = true;
    });
    RawClient client((*listener)->port());
    ASSERT_TRUE(client.send(testing::read_one_register(1, 0)));
    auto held = unit->take(1);
    ASSERT_EQ(held.size(), 1u);
    // The stop request posts the server's stop to its loop before it returns; a handler posted
    // after it runs once the server has taken the stop, and must now wait for the reply owed.
    server.request_stop();
    std::promise<void> stop_taken;
    boost::asio::post(loop, [&stop_taken] { stop_taken.set_value(); });
    ASSERT_EQ(stop_taken.get_future().wait_for(30s), std::future_status::ready) << "the server's loop ended first";
    EXPECT_FALSE(stopped) << "the server stopped with a reply still owed";
    held[0].second(hex("03 02 00 2A"));
    EXPECT_EQ(client.receive(11), hex("00 01 00 00 00 05 01 03 02 00 2A"));
    EXPECT_TRUE(client.closed_by_server_within(1000ms));
    server.join();
    EXPECT_TRUE(stopped);
    EXPECT_TRUE(served.ok()) << served.error().message;
}

TEST(TcpSlaveServer, StopsPromptlyWithClientsConnected) {
    ServedSlave served(UnitMap{{1, std::make_shared<RegisterBank>()}});
    RawClient first(served.port());
    RawClient second(served.port());
    EXPECT_EQ(testing::poll_latency(first, 1) < 1s, true);
    const auto start = testing::Clock::now();
    served.stop();
    EXPECT_LT(testing::Clock::now() - start, 500ms);
    EXPECT_TRUE(served.served_ok());
    EXPECT_TRUE(first.closed_by_server_within(1000ms));
}

std::chrono::nanoseconds process_cpu_time() {
    timespec now{};
    ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
    return std::chrono::seconds(now.tv_sec) + std::chrono::nanoseconds(now.tv_nsec);
}

long voluntary_context_switches() {
    rusage usage{};
    ::getrusage(RUSAGE_SELF, &usage);
    return usage.ru_nvcsw;
}

// No polling: a server with connected, silent clients sleeps until something happens. Its CPU
// time catches a busy loop; its wake-ups (voluntary context switches of the whole process)
// catch a timed poll, which a 20 ms timeout would make 50 times a second. (The bound leaves
// room for a sanitizer's own background thread, which wakes up about ten times a second.)
TEST(TcpSlaveServer, AnIdleServerUsesNoCpuAndDoesNotWakeUp) {
    ServedSlave served(UnitMap{{1, std::make_shared<RegisterBank>()}});
    RawClient client(served.port());
    testing::poll_latency(client, 1);  // the connection is up and served
    const auto cpu_before = process_cpu_time();
    const long switches_before = voluntary_context_switches();
    std::this_thread::sleep_for(1s);  // the idle second being measured
    const auto cpu = process_cpu_time() - cpu_before;
    const long switches = voluntary_context_switches() - switches_before;
    EXPECT_LT(cpu, 50ms) << "CPU used by an idle server in one second";
    EXPECT_LT(switches, 25) << "wake-ups of an idle server in one second";
}

}  // namespace
}  // namespace loopwire::session
