// PDUs passed through the master as they are (Master::forward), as a gateway does for the
// Modbus TCP clients it serves: any function code, the device's exception replies handed back
// unchanged, and errors only for what the device cannot say itself.
#include <gtest/gtest.h>

#include <future>
#include <thread>

#include "codec/rtu.hpp"
#include "codec/tcp.hpp"
#include "scripted_stream.hpp"
#include "session/master.hpp"
#include "simulation/register_bank.hpp"
#include "tcp_test_client.hpp"

namespace loopwire::session {
namespace {

using loopwire::testing::hex;
using loopwire::testing::ScriptedStream;
using loopwire::testing::ScriptStep;
using namespace std::chrono_literals;

struct SerialMasterOnScript {
    ScriptedStream* stream;
    std::unique_ptr<Master> master;
};

SerialMasterOnScript serial_master(std::deque<ScriptStep> script, const std::string& link = "rtu:/dev/null?baud=19200") {
    auto clock = std::make_shared<VirtualClock>();
    MasterOptions options;
    options.clock = clock;
    options.timeout = 1s;
    options.retries = 1;
    auto stream = std::make_unique<ScriptedStream>(std::move(script), clock);
    auto* raw = stream.get();
    return {raw, make_serial_master(std::move(stream), *transport::parse_link_url(link), std::move(options))};
}

// Function 65 (41h) is in the first user-defined range (Modbus application protocol V1.1b3,
// 5): loopwire knows nothing of its layout, so its reply is found by the silence after it.
TEST(MasterForward, AUserDefinedFunctionGoesOutAsGivenAndItsReplyComesBackWhole) {
    const Bytes request = hex("41 01 02 03");
    const Bytes answer = hex("41 AA BB CC DD");
    auto [stream, master] = serial_master({{codec::rtu_encode(9, request), codec::rtu_encode(9, answer)}});
    auto reply = master->forward(9, request);
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(to_hex(*reply), to_hex(answer));
    EXPECT_TRUE(stream->script_done());
}

// The device's exception reply is its answer: handed back for the caller to pass on, not
// turned into an error and not retried.
TEST(MasterForward, AnExceptionReplyIsHandedBackAsTheDeviceSentIt) {
    const Bytes request = hex("2B 0E 01 00");  // read device identification (43 / 14)
    auto [stream, master] = serial_master({{codec::rtu_encode(3, request), codec::rtu_encode(3, hex("AB 01"))}});
    auto reply = master->forward(3, request);
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(to_hex(*reply), "AB 01");
    EXPECT_EQ(stream->writes().size(), 1u);
}

TEST(MasterForward, AStandardFunctionPassesThroughWithItsBytesUnchanged) {
    // AC20 manual, "Function codes 3 and 4: words reading", Example: slave 29 reads 178..180.
    auto [stream, master] = serial_master({{hex("1D 03 00 B2 00 03 A7 B0"), hex("1D 03 06 FF 9C 80 00 05 5A D7 0D")}});
    auto reply = master->forward(29, hex("03 00 B2 00 03"));
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(to_hex(*reply), "03 06 FF 9C 80 00 05 5A");
}

TEST(MasterForward, ASerialReplyOfAnotherFunctionIsABadReplyNamingItsBytes) {
    const Bytes wrong = codec::rtu_encode(4, hex("42 00"));
    auto [stream, master] = serial_master({{codec::rtu_encode(4, hex("41 00")), wrong}});
    auto reply = master->forward(4, hex("41 00"));
    ASSERT_FALSE(reply.ok());
    EXPECT_EQ(reply.error().kind, ErrorKind::mismatch) << reply.error().message;
    EXPECT_NE(reply.error().message.find(to_hex(wrong)), std::string::npos) << reply.error().message;
    EXPECT_NE(reply.error().message.find("function 65 (41h)"), std::string::npos) << reply.error().message;
}

TEST(MasterForward, SilenceIsATimeoutThatNamesTheFunctionAndTheTries) {
    const Bytes frame = codec::rtu_encode(5, hex("64 10"));
    auto [stream, master] = serial_master({{frame, std::nullopt}, {frame, std::nullopt}});
    auto reply = master->forward(5, hex("64 10"));
    ASSERT_FALSE(reply.ok());
    EXPECT_EQ(reply.error().kind, ErrorKind::timeout);
    EXPECT_NE(reply.error().message.find("function 100 (64h), 2 bytes, to unit 5"), std::string::npos) << reply.error().message;
    EXPECT_NE(reply.error().message.find("2 tries"), std::string::npos) << reply.error().message;
}

TEST(MasterForward, ABroadcastAwaitsNothingAndReturnsAnEmptyPdu) {
    const Bytes request = hex("41 05");
    auto [stream, master] = serial_master({{codec::rtu_encode(0, request), std::nullopt}});
    auto reply = master->forward(0, request);
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_TRUE(reply->empty());
}

TEST(MasterForward, WhatIsNotAModbusPduIsRefusedBeforeAnythingIsSent) {
    const std::vector<std::pair<const char*, Bytes>> cases{
        {"empty", Bytes{}},
        {"function code 0", hex("00 01")},
        {"an exception code", hex("83 02")},
        {"254 bytes", Bytes(254, 0x41)},
    };
    for (const auto& [what, pdu] : cases) {
        auto [stream, master] = serial_master({});
        auto reply = master->forward(1, pdu);
        ASSERT_FALSE(reply.ok()) << what;
        EXPECT_EQ(reply.error().kind, ErrorKind::usage) << what << ": " << reply.error().message;
        EXPECT_TRUE(stream->writes().empty()) << what;
    }
    auto [stream, master] = serial_master({{codec::rtu_encode(1, Bytes(253, 0x41)), std::nullopt},
                                           {codec::rtu_encode(1, Bytes(253, 0x41)), std::nullopt}});
    EXPECT_EQ(master->forward(1, Bytes(253, 0x41)).error().kind, ErrorKind::timeout) << "253 bytes are allowed";
}

// Ramp/soak manual, chapter 6: a Linking frame carries one register read or write, nothing else.
TEST(MasterForward, LinkingCarriesOnlyWhatItsFramesCanSay) {
    auto [stream, master] = serial_master({}, "linking:/dev/null?baud=38400&parity=odd");
    auto reply = master->forward(1, hex("41 00"));
    ASSERT_FALSE(reply.ok());
    EXPECT_EQ(reply.error().kind, ErrorKind::usage);
    EXPECT_NE(reply.error().message.find("Linking protocol carries one register"), std::string::npos) << reply.error().message;
    EXPECT_TRUE(stream->writes().empty());
}

TEST(MasterForward, ASerialForwardCompletesOnTheMastersThread) {
    const Bytes request = hex("41 01");
    auto [stream, master] = serial_master({{codec::rtu_encode(9, request), codec::rtu_encode(9, hex("41 02"))}});
    std::promise<Result<Bytes>> done;
    master->forward_async(9, request, [&done](Result<Bytes> reply) { done.set_value(std::move(reply)); });
    auto future = done.get_future();
    ASSERT_EQ(future.wait_for(5s), std::future_status::ready) << "no completion within 5 s";
    auto reply = future.get();
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(to_hex(*reply), "41 02");
}

// ---- Modbus TCP --------------------------------------------------------------------------

std::unique_ptr<Master> tcp_master_to(std::uint16_t port, milliseconds timeout = 2000ms) {
    MasterOptions options;
    options.timeout = timeout;
    auto master = open_master(*transport::parse_link_url("tcp://127.0.0.1:" + std::to_string(port)), options);
    EXPECT_TRUE(master.ok()) << master.error().message;
    return master ? std::move(*master) : nullptr;
}

// loopwire's own slave answers function 65 with exception 1 (illegal function): the master
// hands the exception back as the reply, and a read's reply comes back byte for byte.
TEST(MasterForward, OverTcpTheSlavesRepliesComeBackAsTheyWereSent) {
    auto bank = std::make_shared<RegisterBank>();
    bank->set(Table::holding_registers, 7, 0x1234);
    testing::ServedSlave served(UnitMap{{1, bank}});
    auto master = tcp_master_to(served.port());
    ASSERT_TRUE(master);
    auto unknown = master->forward(1, hex("41 00 01"));
    ASSERT_TRUE(unknown.ok()) << unknown.error().message;
    EXPECT_EQ(to_hex(*unknown), "C1 01");
    auto read = master->forward(1, hex("03 00 07 00 01"));
    ASSERT_TRUE(read.ok()) << read.error().message;
    EXPECT_EQ(to_hex(*read), "03 02 12 34");
}

// A server that answers every request with `reply` (or each of `replies`, in order) under the
// request's transaction id and `reply_unit`, until the test ends.
class AnsweringServer {
public:
    AnsweringServer(Bytes reply, std::uint8_t reply_unit) : AnsweringServer(std::vector<Bytes>{std::move(reply)}, reply_unit) {}
    AnsweringServer(std::vector<Bytes> replies, std::uint8_t reply_unit) : replies_(std::move(replies)), unit_(reply_unit) {
        auto listener = transport::TcpListener::listen("127.0.0.1", 0);
        if (!listener) throw std::runtime_error(listener.error().message);
        listener_ = std::move(*listener);
        server_ = std::jthread([this](std::stop_token stop) { serve(stop); });
    }
    std::uint16_t port() const { return listener_->port(); }

private:
    void serve(const std::stop_token& stop) {
        auto client = listener_->accept(5s);
        if (!client || !*client) return;
        codec::MbapDecoder decoder;
        std::array<std::uint8_t, 512> buffer{};
        while (!stop.stop_requested()) {
            auto n = (*client)->read_some(buffer, 50ms);
            if (!n || *n == 0) continue;
            auto frames = decoder.feed(ByteView(buffer.data(), *n));
            if (!frames) return;
            for (const auto& frame : *frames) {
                for (const auto& reply : replies_) (void)(*client)->write(codec::mbap_encode(frame.transaction, unit_, reply));
            }
        }
    }

    std::vector<Bytes> replies_;
    std::uint8_t unit_;
    std::unique_ptr<transport::TcpListener> listener_;
    std::jthread server_;
};

TEST(MasterForward, OverTcpAnyFunctionsReplyIsReturnedWhole) {
    AnsweringServer server(hex("64 03 01 02 03"), 2);
    auto master = tcp_master_to(server.port());
    ASSERT_TRUE(master);
    auto reply = master->forward(2, hex("64 00"));
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(to_hex(*reply), "64 03 01 02 03");
}

TEST(MasterForward, OverTcpAReplyOfAnotherFunctionOrUnitIsABadReplyNamingItsBytes) {
    {
        AnsweringServer server(hex("65 00"), 2);
        auto master = tcp_master_to(server.port());
        ASSERT_TRUE(master);
        auto reply = master->forward(2, hex("64 00"));
        ASSERT_FALSE(reply.ok());
        EXPECT_EQ(reply.error().kind, ErrorKind::mismatch) << reply.error().message;
        EXPECT_NE(reply.error().message.find("65 00"), std::string::npos) << reply.error().message;
    }
    {
        AnsweringServer server(hex("64 00"), 3);
        auto master = tcp_master_to(server.port());
        ASSERT_TRUE(master);
        auto reply = master->forward(2, hex("64 00"));
        ASSERT_FALSE(reply.ok());
        EXPECT_EQ(reply.error().kind, ErrorKind::mismatch) << reply.error().message;
        EXPECT_NE(reply.error().message.find("unit 3"), std::string::npos) << reply.error().message;
    }
}

// Transaction id, unit and shape: a frame with the awaited id whose byte count is not what was
// asked is discarded, and the right reply after it is taken.
TEST(MasterForward, OverTcpAReplyOfTheWrongShapeIsSkippedForTheRightOne) {
    AnsweringServer server(std::vector<Bytes>{hex("03 04 00 14 00 15"), hex("03 02 03 09")}, 2);
    auto master = tcp_master_to(server.port());
    ASSERT_TRUE(master);
    auto reply = master->forward(2, hex("03 03 09 00 01"));
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(to_hex(*reply), "03 02 03 09");
}

TEST(MasterForward, OverTcpOnlyAReplyOfTheWrongShapeIsABadReplyAtTheDeadline) {
    AnsweringServer server(hex("03 04 00 14 00 15"), 2);
    auto master = tcp_master_to(server.port(), 300ms);
    ASSERT_TRUE(master);
    auto reply = master->forward(2, hex("03 03 09 00 01"));
    ASSERT_FALSE(reply.ok());
    EXPECT_EQ(reply.error().kind, ErrorKind::mismatch) << reply.error().message;
    EXPECT_NE(reply.error().message.find("byte count 4, the request asked for 2 bytes"), std::string::npos)
        << reply.error().message;
}

// On RTU an exception reply's length is fixed by its function code (the decoder would not find
// a longer one), over TCP the MBAP header carries whatever length the server says.
TEST(MasterForward, OverTcpAnExceptionReplyOfTheWrongLengthIsNotAnAnswer) {
    AnsweringServer server(hex("E4 01 00"), 2);
    auto master = tcp_master_to(server.port());
    ASSERT_TRUE(master);
    auto reply = master->forward(2, hex("64 00"));
    ASSERT_FALSE(reply.ok());
    EXPECT_EQ(reply.error().kind, ErrorKind::malformed) << reply.error().message;
    EXPECT_NE(reply.error().message.find("E4 01 00"), std::string::npos) << reply.error().message;
}

TEST(MasterForward, OverTcpSilenceIsATimeoutNamingTheFunction) {
    auto listener = transport::TcpListener::listen("127.0.0.1", 0);
    ASSERT_TRUE(listener.ok());
    auto master = tcp_master_to((*listener)->port(), 100ms);
    ASSERT_TRUE(master);
    auto accepted = (*listener)->accept(1s);  // accepted, never answered
    auto reply = master->forward(1, hex("41 00"));
    ASSERT_FALSE(reply.ok());
    EXPECT_EQ(reply.error().kind, ErrorKind::timeout);
    EXPECT_NE(reply.error().message.find("function 65 (41h)"), std::string::npos) << reply.error().message;
}

TEST(MasterForward, OverTcpWhatIsNotAModbusPduIsRefused) {
    auto listener = transport::TcpListener::listen("127.0.0.1", 0);
    ASSERT_TRUE(listener.ok());
    auto master = tcp_master_to((*listener)->port());
    ASSERT_TRUE(master);
    EXPECT_EQ(master->forward(1, hex("80 00")).error().kind, ErrorKind::usage);
    EXPECT_EQ(master->forward(1, Bytes{}).error().kind, ErrorKind::usage);
}

}  // namespace
}  // namespace loopwire::session
