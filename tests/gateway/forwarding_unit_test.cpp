// The Modbus TCP front's unit handler: what it passes to the line, what it refuses itself, and
// the exception replies a gateway gives (Modbus application protocol V1.1b3, 7).
#include <gtest/gtest.h>

#include <atomic>
#include <deque>
#include <mutex>

#include "gateway/forwarding_unit.hpp"
#include "support/test_bytes.hpp"

namespace loopwire::gateway {
namespace {

using loopwire::testing::hex;

// A line whose requests the test answers by hand, in order.
class HandAnsweredLine final : public session::Master {
public:
    struct Sent {
        std::uint8_t unit;
        Bytes pdu;
        ForwardCompletion done;
    };

    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override { return make_error(ErrorKind::usage, "not used"); }
    void execute_async(std::uint8_t, codec::Request, Completion done) override { done(make_error(ErrorKind::usage, "not used")); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return make_error(ErrorKind::usage, "not used"); }
    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override {
        std::lock_guard lock(mutex_);
        sent_.push_back({unit, std::move(pdu), std::move(done)});
    }
    std::string describe() const override { return "hand-answered line"; }

    std::size_t sent() const {
        std::lock_guard lock(mutex_);
        return sent_.size();
    }
    // Answers the oldest request not answered yet; returns what it was.
    Sent answer(Result<Bytes> reply) {
        Sent oldest;
        {
            std::lock_guard lock(mutex_);
            oldest = std::move(sent_.at(answered_++));
        }
        auto done = std::move(oldest.done);
        done(std::move(reply));
        return oldest;
    }

private:
    mutable std::mutex mutex_;
    std::deque<Sent> sent_;
    std::size_t answered_ = 0;
};

struct Replies {
    std::vector<std::optional<Bytes>> got;
    session::UnitHandler::ReplyCallback collect() {
        return [this](std::optional<Bytes> reply) { got.push_back(std::move(reply)); };
    }
};

struct Front {
    std::shared_ptr<HandAnsweredLine> line = std::make_shared<HandAnsweredLine>();
    std::shared_ptr<LineScheduler> scheduler = std::make_shared<LineScheduler>(line);
    std::vector<std::string> log;

    std::shared_ptr<ForwardingUnit> unit(ForwardingSettings settings) {
        return std::make_shared<ForwardingUnit>(scheduler, settings, steady_clock(),
                                                [this](const std::string& line_text) { log.push_back(line_text); });
    }
};

TEST(ForwardingUnit, TheRequestGoesToTheDevicesUnitOnItsLineAndItsReplyBackUnchanged) {
    Front front;
    auto unit = front.unit({.line_unit = 3});
    Replies replies;
    unit->handle_async(hex("03 00 19 00 02"), false, 1, replies.collect());
    ASSERT_EQ(front.line->sent(), 1u);
    auto sent = front.line->answer(hex("03 04 00 0A 00 14"));
    EXPECT_EQ(sent.unit, 3);
    EXPECT_EQ(to_hex(sent.pdu), "03 00 19 00 02");
    ASSERT_EQ(replies.got.size(), 1u);
    EXPECT_EQ(to_hex(*replies.got[0]), "03 04 00 0A 00 14");
}

TEST(ForwardingUnit, ASilentOrWrongAnsweringDeviceIsException0Bh) {
    for (auto kind : {ErrorKind::timeout, ErrorKind::mismatch, ErrorKind::malformed}) {
        Front front;
        auto unit = front.unit({.line_unit = 4});
        Replies replies;
        unit->handle_async(hex("03 00 00 00 01"), false, 1, replies.collect());
        front.line->answer(make_error(kind, "no luck"));
        ASSERT_EQ(replies.got.size(), 1u);
        EXPECT_EQ(to_hex(*replies.got[0]), "83 0B") << static_cast<int>(kind);
    }
}

// Modbus application protocol V1.1b3, 7: 0Ah, gateway path unavailable. The line is down (or
// failed under the request), so the device was never asked: 0Bh would blame the device.
TEST(ForwardingUnit, ALineThatIsDownIsException0Ah) {
    Front front;
    auto unit = front.unit({.line_unit = 4});
    Replies replies;
    unit->handle_async(hex("03 00 00 00 01"), false, 1, replies.collect());
    front.line->answer(make_error(ErrorKind::link, "line furnace (rtu:/dev/ttyUSB0) is down: no such port; retrying in 4 s"));
    ASSERT_EQ(replies.got.size(), 1u);
    EXPECT_EQ(to_hex(*replies.got[0]), "83 0A");
}

TEST(ForwardingUnit, ARequestTheLinesFramingCannotCarryIsIllegalFunction) {
    Front front;
    auto unit = front.unit({.line_unit = 1});
    Replies replies;
    unit->handle_async(hex("41 00"), false, 1, replies.collect());
    front.line->answer(make_error(ErrorKind::usage, "the Linking protocol carries one register read or write per request"));
    ASSERT_EQ(replies.got.size(), 1u);
    EXPECT_EQ(to_hex(*replies.got[0]), "C1 01");
}

// A client's raw write may move a word that bounds a polled value (gateway.cpp tells the polls):
// the unit says so for each write the device took, and for nothing else.
TEST(ForwardingUnit, AWriteTheDeviceTookIsToldAndNothingElse) {
    Front front;
    int told = 0;
    auto unit = front.unit({.line_unit = 3, .on_write_answered = [&told] { ++told; }});
    Replies replies;
    unit->handle_async(hex("06 02 CC 02 58"), false, 1, replies.collect());
    front.line->answer(hex("06 02 CC 02 58"));
    EXPECT_EQ(told, 1) << "a write the device echoed";
    unit->handle_async(hex("06 02 CC 7F FF"), false, 1, replies.collect());
    front.line->answer(hex("86 03"));
    unit->handle_async(hex("10 02 CC 00 01 02 00 01"), false, 1, replies.collect());
    front.line->answer(make_error(ErrorKind::timeout, "no reply"));
    unit->handle_async(hex("03 02 CC 00 01"), false, 1, replies.collect());
    front.line->answer(hex("03 02 02 58"));
    EXPECT_EQ(told, 1) << "an exception reply, a timeout or a read was told as a write taken";
    ASSERT_EQ(replies.got.size(), 4u);
}

TEST(ForwardingUnit, AReadOnlyGatewayRefusesWritesItselfAndLogsThem) {
    Front front;
    auto unit = front.unit({.line_unit = 3, .writes_allowed = false});
    Replies replies;
    for (const char* write : {"06 03 02 00 0A", "10 00 00 00 01 02 00 01", "05 00 00 FF 00", "41 00", "16 00 00 FF FF 00 00"}) {
        unit->handle_async(hex(write), false, 1, replies.collect());
    }
    EXPECT_EQ(front.line->sent(), 0u) << "a refused write reached the line";
    ASSERT_EQ(replies.got.size(), 5u);
    EXPECT_EQ(to_hex(*replies.got[0]), "86 01");
    EXPECT_EQ(to_hex(*replies.got[3]), "C1 01");
    ASSERT_EQ(front.log.size(), 5u);
    EXPECT_NE(front.log[0].find("read-only"), std::string::npos) << front.log[0];

    unit->handle_async(hex("03 00 00 00 01"), false, 1, replies.collect());
    EXPECT_EQ(front.line->sent(), 1u) << "a read of a read-only gateway must still pass";
}

// A unit-0 request goes out once per line, as a broadcast, from the one unit that carries them;
// nobody answers it.
TEST(ForwardingUnit, ABroadcastGoesOutOnceAsUnitZero) {
    Front front;
    auto carrier = front.unit({.line_unit = 3, .carries_broadcasts = true});
    auto other = front.unit({.line_unit = 5});
    Replies replies;
    carrier->handle_async(hex("06 00 00 00 07"), true, 1, replies.collect());
    other->handle_async(hex("06 00 00 00 07"), true, 1, replies.collect());
    ASSERT_EQ(front.line->sent(), 1u);
    auto sent = front.line->answer(Bytes{});
    EXPECT_EQ(sent.unit, 0);
    ASSERT_EQ(replies.got.size(), 2u);
    EXPECT_FALSE(replies.got[0].has_value());
    EXPECT_FALSE(replies.got[1].has_value());
}

// While the line is busy, a write queued after a read goes out first.
TEST(ForwardingUnit, WritesAreQueuedAheadOfReads) {
    Front front;
    auto unit = front.unit({.line_unit = 3});
    Replies replies;
    unit->handle_async(hex("03 00 00 00 01"), false, 1, replies.collect());  // on the wire
    unit->handle_async(hex("03 00 01 00 01"), false, 2, replies.collect());
    unit->handle_async(hex("06 00 02 00 09"), false, 3, replies.collect());
    front.line->answer(hex("03 02 00 00"));
    ASSERT_EQ(front.line->sent(), 2u);
    auto second = front.line->answer(hex("06 00 02 00 09"));
    EXPECT_EQ(second.pdu[0], 0x06);
}

TEST(ForwardingUnit, ASerialFrontWaitsForTheLine) {
    Front front;
    auto unit = front.unit({.line_unit = 3});
    std::thread answering([&] {
        while (front.line->sent() == 0) std::this_thread::yield();
        front.line->answer(hex("03 02 00 2A"));
    });
    auto reply = unit->handle(hex("03 00 00 00 01"), false);
    answering.join();
    ASSERT_TRUE(reply.has_value());
    EXPECT_EQ(to_hex(*reply), "03 02 00 2A");
}

// --- The read cache (max_age) ----------------------------------------------------------------

using namespace std::chrono_literals;

// A front on virtual time, its units caching reads for 500 ms.
struct CachingFront {
    // First, so that it goes last: the scheduler fails what is still queued when it goes, and
    // those requests reply here.
    Replies replies;
    std::shared_ptr<VirtualClock> clock = std::make_shared<VirtualClock>();
    std::shared_ptr<HandAnsweredLine> line = std::make_shared<HandAnsweredLine>();
    std::shared_ptr<LineScheduler> scheduler = std::make_shared<LineScheduler>(line, LineSchedulerOptions{}, clock);

    std::shared_ptr<ForwardingUnit> unit(ForwardingSettings settings = {.line_unit = 3, .max_age = 500ms}) {
        return std::make_shared<ForwardingUnit>(scheduler, settings, clock);
    }
};

TEST(ForwardingUnitCache, ARepeatedReadWithinMaxAgeIsAnsweredWithoutTheLine) {
    CachingFront front;
    auto unit = front.unit();
    auto& replies = front.replies;
    unit->handle_async(hex("03 00 19 00 02"), false, 1, replies.collect());
    front.line->answer(hex("03 04 00 0A 00 14"));
    front.clock->advance(500ms);
    unit->handle_async(hex("03 00 19 00 02"), false, 2, replies.collect());
    EXPECT_EQ(front.line->sent(), 1u) << "the second read went to the line";
    ASSERT_EQ(replies.got.size(), 2u);
    EXPECT_EQ(to_hex(*replies.got[1]), "03 04 00 0A 00 14");
    EXPECT_EQ(front.scheduler->statistics().sent, 1u);
}

TEST(ForwardingUnitCache, AReadPastMaxAgeGoesToTheLine) {
    CachingFront front;
    auto unit = front.unit();
    auto& replies = front.replies;
    unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    front.line->answer(hex("03 02 00 0A"));
    front.clock->advance(501ms);
    unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    ASSERT_EQ(front.line->sent(), 2u);
    front.line->answer(hex("03 02 00 0B"));
    ASSERT_EQ(replies.got.size(), 2u);
    EXPECT_EQ(to_hex(*replies.got[1]), "03 02 00 0B");
}

TEST(ForwardingUnitCache, ADifferentRequestGoesToTheLine) {
    CachingFront front;
    auto unit = front.unit();
    auto& replies = front.replies;
    unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    front.line->answer(hex("03 02 00 0A"));
    unit->handle_async(hex("03 00 1A 00 01"), false, 1, replies.collect());
    unit->handle_async(hex("04 00 19 00 01"), false, 1, replies.collect());
    EXPECT_EQ(front.line->sent(), 2u);
}

TEST(ForwardingUnitCache, EachDeviceHasItsOwnCache) {
    CachingFront front;
    auto oven = front.unit({.line_unit = 3, .max_age = 500ms});
    auto kiln = front.unit({.line_unit = 4, .max_age = 500ms});
    auto& replies = front.replies;
    oven->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    front.line->answer(hex("03 02 00 0A"));
    kiln->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    ASSERT_EQ(front.line->sent(), 2u);
    EXPECT_EQ(front.line->answer(hex("03 02 00 0B")).unit, 4);
}

// A client that reads after its own write must see what it wrote.
TEST(ForwardingUnitCache, AWriteEmptiesTheCacheOfItsUnit) {
    for (const char* write : {"06 00 19 00 07", "10 00 19 00 01 02 00 07", "05 00 00 FF 00", "41 00"}) {
        CachingFront front;
        auto unit = front.unit();
        auto& replies = front.replies;
        unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
        front.line->answer(hex("03 02 00 0A"));
        unit->handle_async(hex(write), false, 1, replies.collect());
        front.line->answer(hex(write));
        unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
        ASSERT_EQ(front.line->sent(), 3u) << write;
        front.line->answer(hex("03 02 00 07"));
        EXPECT_EQ(to_hex(*replies.got.back()), "03 02 00 07") << write;
    }
}

// A read on the wire when a write is taken may carry the value from before the write: its reply
// is not kept, so a read taken after the write waits for the line.
TEST(ForwardingUnitCache, AReadAnsweredAroundAWriteIsNotKept) {
    CachingFront front;
    auto unit = front.unit();
    auto& replies = front.replies;
    unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());  // on the wire
    unit->handle_async(hex("06 00 19 00 07"), false, 2, replies.collect());  // queued
    front.line->answer(hex("03 02 00 0A"));
    unit->handle_async(hex("03 00 19 00 01"), false, 2, replies.collect());
    EXPECT_EQ(replies.got.size(), 1u) << "the read taken after the write was answered with the value from before it";
    front.line->answer(hex("06 00 19 00 07"));
    ASSERT_EQ(front.line->sent(), 3u);
    front.line->answer(hex("03 02 00 07"));
    ASSERT_EQ(replies.got.size(), 3u);
    EXPECT_EQ(to_hex(*replies.got[2]), "03 02 00 07");
}

TEST(ForwardingUnitCache, ABroadcastWriteEmptiesTheCachesOfUnitsThatDoNotCarryIt) {
    CachingFront front;
    auto carrier = front.unit({.line_unit = 3, .carries_broadcasts = true, .max_age = 500ms});
    auto other = front.unit({.line_unit = 4, .max_age = 500ms});
    auto& replies = front.replies;
    other->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    front.line->answer(hex("03 02 00 0A"));
    carrier->handle_async(hex("06 00 19 00 07"), true, 1, replies.collect());
    other->handle_async(hex("06 00 19 00 07"), true, 1, replies.collect());
    front.line->answer(Bytes{});
    other->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    EXPECT_EQ(front.line->sent(), 3u);
}

TEST(ForwardingUnitCache, ExceptionsAndFailuresAreNotKept) {
    CachingFront front;
    auto unit = front.unit();
    auto& replies = front.replies;
    unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    front.line->answer(hex("83 02"));
    unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    ASSERT_EQ(front.line->sent(), 2u) << "an exception reply was kept";
    front.line->answer(make_error(ErrorKind::timeout, "no reply"));
    unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    ASSERT_EQ(front.line->sent(), 3u) << "a failure was kept";
    ASSERT_EQ(replies.got.size(), 2u);
    EXPECT_EQ(to_hex(*replies.got[1]), "83 0B");
}

TEST(ForwardingUnitCache, OtherReadingFunctionsAlwaysGoToTheLine) {
    CachingFront front;
    auto unit = front.unit();
    auto& replies = front.replies;
    unit->handle_async(hex("07"), false, 1, replies.collect());
    front.line->answer(hex("07 00"));
    unit->handle_async(hex("07"), false, 1, replies.collect());
    EXPECT_EQ(front.line->sent(), 2u);
}

TEST(ForwardingUnitCache, WithoutMaxAgeEveryReadGoesToTheLine) {
    CachingFront front;
    auto unit = front.unit({.line_unit = 3});
    auto& replies = front.replies;
    unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    front.line->answer(hex("03 02 00 0A"));
    unit->handle_async(hex("03 00 19 00 01"), false, 1, replies.collect());
    EXPECT_EQ(front.line->sent(), 2u);
}

TEST(ForwardingUnit, OnlyReadingFunctionsCountAsReads) {
    for (int f : {1, 2, 3, 4, 7, 11, 12, 17, 20, 24, 43}) EXPECT_TRUE(only_reads(static_cast<std::uint8_t>(f))) << f;
    for (int f : {5, 6, 8, 15, 16, 21, 22, 23, 65, 100}) EXPECT_FALSE(only_reads(static_cast<std::uint8_t>(f))) << f;
}

// A line whose queue is full refuses with 06h (server device busy), which the client gets as
// the exception reply: the device is not absent (0Bh), the gateway is busy, try again later.
TEST(ForwardingUnit, AFullLineQueueIsAnsweredServerDeviceBusy) {
    auto line = std::make_shared<HandAnsweredLine>();
    LineSchedulerOptions options;
    options.max_queued = 1;
    auto scheduler = std::make_shared<LineScheduler>(line, options);
    auto unit = std::make_shared<ForwardingUnit>(scheduler, ForwardingSettings{}, steady_clock());
    Replies replies;
    unit->handle_async(hex("03 00 00 00 01"), false, 1, replies.collect());  // on the wire
    unit->handle_async(hex("03 00 01 00 01"), false, 2, replies.collect());  // queued
    unit->handle_async(hex("03 00 02 00 01"), false, 3, replies.collect());  // past the bound
    ASSERT_EQ(replies.got.size(), 1U);
    EXPECT_EQ(replies.got[0], hex("83 06"));
    line->answer(hex("03 02 00 01"));
    line->answer(hex("03 02 00 02"));
    EXPECT_EQ(line->sent(), 2U);
}

// A request whose asker no longer wants it (its connection closed while it waited) never
// reaches the line, and the line counts it abandoned.
TEST(ForwardingUnit, ARequestItsAskerNoLongerWantsNeverReachesTheLine) {
    Front front;
    auto unit = front.unit(ForwardingSettings{});
    Replies replies;
    unit->handle_async(hex("03 00 00 00 01"), false, 1, replies.collect());  // on the wire
    auto open = std::make_shared<std::atomic<bool>>(true);
    const session::UnitHandler::Asker closing(2, open);
    unit->handle_async(hex("03 00 01 00 01"), false, closing, replies.collect());
    open->store(false);
    front.line->answer(hex("03 02 00 01"));
    EXPECT_EQ(front.line->sent(), 1U) << "the closed connection's request went on the line";
    EXPECT_EQ(front.scheduler->statistics().abandoned, 1U);
    ASSERT_EQ(replies.got.size(), 2U);
    EXPECT_EQ(replies.got[1], hex("83 0A"));  // to nobody: the connection has gone; never sent, so not 0Bh
}

}  // namespace
}  // namespace loopwire::gateway
