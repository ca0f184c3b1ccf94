// The gateway's Modbus TCP front end to end in one process: real loopback connections to a TCP
// slave whose units are ForwardingUnits on a line the test answers by hand, so it can count
// exactly what reached the line.
#include <gtest/gtest.h>

#include <sys/socket.h>

#include <deque>
#include <initializer_list>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "gateway/forwarding_unit.hpp"
#include "session/tcp_test_client.hpp"
#include "support/eventually.hpp"
#include "support/test_bytes.hpp"

namespace loopwire::gateway {
namespace {

using loopwire::testing::eventually;
using loopwire::testing::hex;
using session::testing::RawClient;
using namespace std::chrono_literals;

constexpr auto patience = 30s;

// A line that holds each request until the test answers it; answers come in order.
class HeldLine final : public session::Master {
public:
    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override { return make_error(ErrorKind::usage, "not used"); }
    void execute_async(std::uint8_t, codec::Request, Completion done) override { done(make_error(ErrorKind::usage, "not used")); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return make_error(ErrorKind::usage, "not used"); }
    void forward_async(std::uint8_t, Bytes pdu, ForwardCompletion done) override {
        std::lock_guard lock(mutex_);
        sent_.push_back(std::move(pdu));
        held_.push_back(std::move(done));
    }
    std::string describe() const override { return "held line"; }

    std::vector<Bytes> sent() const {
        std::lock_guard lock(mutex_);
        return sent_;
    }
    void answer_oldest(Bytes reply) {
        ForwardCompletion done;
        {
            std::lock_guard lock(mutex_);
            ASSERT_FALSE(held_.empty()) << "nothing on the line";
            done = std::move(held_.front());
            held_.pop_front();
        }
        done(std::move(reply));
    }

private:
    mutable std::mutex mutex_;
    std::vector<Bytes> sent_;
    std::deque<ForwardCompletion> held_;
};

// What the front traced, for the test to wait on.
class TraceNotes {
public:
    session::TraceSink sink() {
        return [this](const session::TraceEvent& event) {
            std::lock_guard lock(mutex_);
            notes_.push_back(event.note);
        };
    }
    std::string all() {
        std::lock_guard lock(mutex_);
        std::string joined;
        for (const auto& note : notes_) joined += note + "\n";
        return joined;
    }
    bool saw(const std::string& part) {
        std::lock_guard lock(mutex_);
        for (const auto& note : notes_) {
            if (note.find(part) != std::string::npos) return true;
        }
        return false;
    }

private:
    std::mutex mutex_;
    std::vector<std::string> notes_;
};

Bytes read_register(std::uint16_t transaction, std::uint16_t address) {
    return session::testing::read_one_register(transaction, address);
}

class ModbusFront : public ::testing::Test {
protected:
    session::SlaveOptions front_options() {
        session::SlaveOptions options;
        options.trace = notes.sink();
        return options;
    }

    TraceNotes notes;
    std::shared_ptr<HeldLine> line = std::make_shared<HeldLine>();
    std::shared_ptr<LineScheduler> scheduler = std::make_shared<LineScheduler>(line);
    session::testing::ServedSlave served{
        session::UnitMap{{1, std::make_shared<ForwardingUnit>(scheduler, ForwardingSettings{}, steady_clock())}},
        "tcp://127.0.0.1:0", front_options()};
};

// Requests queued for the line by a connection that then goes -- reset, or ended by its client
// after sending (connect, send, close) -- are dropped before they reach the line and counted
// abandoned; the client still connected is served next.
TEST_F(ModbusFront, RequestsOfAConnectionThatHasGoneNeverReachTheLine) {
    RawClient honest(served.port());
    auto resetting = std::make_unique<RawClient>(served.port());
    RawClient sends_and_closes(served.port());
    ASSERT_TRUE(honest.send(read_register(1, 100)));
    ASSERT_TRUE(eventually([&] { return line->sent().size() == 1; })) << "the first request did not reach the line";
    Bytes two;
    for (const std::uint16_t transaction : std::initializer_list<std::uint16_t>{1, 2}) {
        const Bytes one = read_register(transaction, 200);
        two.insert(two.end(), one.begin(), one.end());
    }
    ASSERT_TRUE(resetting->send(two));
    ASSERT_TRUE(sends_and_closes.send(read_register(1, 300)));
    ASSERT_TRUE(eventually([&] { return scheduler->statistics().queued == 3; })) << "the three requests were not queued";

    const linger abort_on_close{1, 0};
    ASSERT_EQ(::setsockopt(resetting->fd(), SOL_SOCKET, SO_LINGER, &abort_on_close, sizeof abort_on_close), 0);
    resetting.reset();
    ::shutdown(sends_and_closes.fd(), SHUT_WR);
    ASSERT_TRUE(eventually([&] { return served.slave().tcp_statistics().open == 2; })) << "the reset connection stayed open";
    ASSERT_TRUE(eventually([&] { return notes.saw("the client ended the connection"); }))
        << "the end of the connect-send-close client was not seen; traced:\n" << notes.all();

    line->answer_oldest(hex("03 02 00 64"));
    EXPECT_EQ(honest.receive(11, 10000ms), hex("00 01 00 00 00 05 01 03 02 00 64"));
    ASSERT_TRUE(honest.send(read_register(2, 101)));
    ASSERT_TRUE(eventually([&] { return line->sent().size() == 2; }));
    const auto sent = line->sent();
    EXPECT_EQ(sent[1], hex("03 00 65 00 01")) << "a request of a connection that had gone took the line";
    EXPECT_EQ(scheduler->statistics().abandoned, 3u);
    line->answer_oldest(hex("03 02 00 65"));
    EXPECT_EQ(honest.receive(11, 10000ms), hex("00 02 00 00 00 05 01 03 02 00 65"));
}

}  // namespace
}  // namespace loopwire::gateway
