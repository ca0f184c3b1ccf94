// The serial master never hands out a reply that may be another request's: replies
// that come after the timeout, duplicated replies, cut-short and corrupted ones. First in virtual
// time against a line whose arrivals the test schedules to the microsecond, then in wall time on
// the virtual bus with a real slave and random faults.
#include <gtest/gtest.h>

#include <functional>
#include <iostream>
#include <map>
#include <mutex>
#include <random>
#include <thread>

#include <fmt/format.h>

#include "codec/rtu.hpp"
#include "session/master.hpp"
#include "session/slave.hpp"
#include "simulation/register_bank.hpp"
#include "support/test_bytes.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::session {
namespace {

using namespace std::chrono_literals;

// A serial line in virtual time whose device is the test: on every request written it may
// schedule any bytes at any later instant, several at once, overlapping the next request's.
// (The scripted stream of the other tests holds one answer per request, which cannot model a
// reply that outlives its request.)
class TimedLine final : public transport::ByteStream {
public:
    using Device = std::function<void(TimedLine& line, ByteView request, Instant at)>;

    TimedLine(std::shared_ptr<VirtualClock> clock, Device device) : clock_(std::move(clock)), device_(std::move(device)) {}

    void arrive(Instant at, Bytes bytes) { arrivals_.emplace(at, std::move(bytes)); }

    Result<void> write(ByteView bytes) override {
        writes_.push_back(clock_->now());
        device_(*this, bytes, clock_->now());
        return {};
    }

    // Jumps to the first arrival within `timeout` and returns every arrival due by then.
    Result<std::size_t> read_some(std::span<std::uint8_t> buffer, std::chrono::milliseconds timeout) override {
        const Instant until = clock_->now() + timeout;
        if (arrivals_.empty() || arrivals_.begin()->first > until) {
            clock_->sleep_until(until);
            return std::size_t{0};
        }
        clock_->sleep_until(arrivals_.begin()->first);
        std::size_t count = 0;
        while (!arrivals_.empty() && arrivals_.begin()->first <= clock_->now() &&
               count + arrivals_.begin()->second.size() <= buffer.size()) {
            for (std::uint8_t byte : arrivals_.begin()->second) buffer[count++] = byte;
            arrivals_.erase(arrivals_.begin());
        }
        return count;
    }

    void discard_input() override {
        while (!arrivals_.empty() && arrivals_.begin()->first <= clock_->now()) arrivals_.erase(arrivals_.begin());
    }
    int poll_handle() const override { return -1; }
    std::string describe() const override { return "timed line"; }

    const std::vector<Instant>& writes() const { return writes_; }

private:
    std::shared_ptr<VirtualClock> clock_;
    Device device_;
    std::multimap<Instant, Bytes> arrivals_;
    std::vector<Instant> writes_;
};

constexpr std::uint8_t unit = 1;
constexpr auto latency = 5ms;  // how long the device takes to answer, from the end of a request

// What register N holds on the device: N + 1000, so every read has its own value.
std::uint16_t value_at(std::uint16_t address) { return static_cast<std::uint16_t>(address + 1000); }

Bytes read_pdu(std::uint16_t address, std::uint16_t count = 1) {
    Bytes pdu{0x03};
    append_be16(pdu, address);
    append_be16(pdu, count);
    return pdu;
}

// The device's reply PDU to read_pdu(address, count).
Bytes reply_pdu(std::uint16_t address, std::uint16_t count = 1) {
    Bytes pdu{0x03, static_cast<std::uint8_t>(2 * count)};
    for (std::uint16_t i = 0; i < count; ++i) append_be16(pdu, value_at(static_cast<std::uint16_t>(address + i)));
    return pdu;
}

// The reply frame to an RTU read request frame.
Bytes reply_frame_to(ByteView request) {
    const std::uint16_t address = read_be16(request, 2);
    const std::uint16_t count = read_be16(request, 4);
    return codec::rtu_encode(unit, reply_pdu(address, count));
}

transport::LinkUrl rtu_link() { return *transport::parse_link_url("rtu:/dev/null?baud=19200"); }

struct TracedMaster {
    std::shared_ptr<VirtualClock> clock = std::make_shared<VirtualClock>();
    TimedLine* line = nullptr;
    std::unique_ptr<Master> master;
    std::vector<TraceEvent> trace;

    // `device` decides, per request (counted from 0), what arrives when.
    explicit TracedMaster(std::function<void(TimedLine&, ByteView, Instant, unsigned)> device,
                          std::optional<std::chrono::milliseconds> late_reply_window = std::nullopt, unsigned retries = 0) {
        auto counted = [device = std::move(device), n = 0u](TimedLine& l, ByteView request, Instant at) mutable {
            device(l, request, at, n++);
        };
        auto stream = std::make_unique<TimedLine>(clock, std::move(counted));
        line = stream.get();
        MasterOptions options;
        options.timeout = 1s;
        options.late_reply_window = late_reply_window;
        options.retries = retries;
        options.clock = clock;
        options.trace = [this](const TraceEvent& event) { trace.push_back(event); };
        master = make_serial_master(std::move(stream), rtu_link(), options);
    }

    std::size_t discarded_with(const std::string& words) const {
        std::size_t count = 0;
        for (const auto& event : trace) {
            if (event.direction == TraceDirection::discarded && event.note.find(words) != std::string::npos) ++count;
        }
        return count;
    }
};

// The field report: a read of register 777 answered with another client's value, because the
// reply to the read before came after its timeout and both were reads of one register.
TEST(StrayReplies, AReplyThatComesAfterTheTimeoutIsNeverTakenForTheNextRequest) {
    TracedMaster m([](TimedLine& line, ByteView request, Instant at, unsigned n) {
        // The first reply comes 1.5 s late; the second request's reply would come after it.
        line.arrive(at + (n == 0 ? 1500ms : 600ms), reply_frame_to(request));
    });
    auto first = m.master->forward(unit, read_pdu(20));
    ASSERT_FALSE(first.ok());
    EXPECT_EQ(first.error().kind, ErrorKind::timeout);

    auto second = m.master->forward(unit, read_pdu(777));
    ASSERT_TRUE(second.ok()) << second.error().message;
    EXPECT_EQ(to_hex(*second), to_hex(reply_pdu(777)));
    // The second request left only once the line had been quiet for the window (the timeout)
    // after the late reply.
    ASSERT_EQ(m.line->writes().size(), 2u);
    EXPECT_GE(m.line->writes()[1] - m.line->writes()[0], 1500ms + 1s);
    EXPECT_EQ(m.discarded_with("late reply from unit 1"), 1u);
}

TEST(StrayReplies, TheLateReplyWindowIsAnOptionAndCostsNothingAfterAnAnsweredRequest) {
    TracedMaster m(
        [](TimedLine& line, ByteView request, Instant at, unsigned n) {
            if (n != 1) line.arrive(at + latency, reply_frame_to(request));  // the second request goes unanswered
        },
        200ms);
    ASSERT_TRUE(m.master->forward(unit, read_pdu(1)).ok());
    ASSERT_FALSE(m.master->forward(unit, read_pdu(2)).ok());
    ASSERT_TRUE(m.master->forward(unit, read_pdu(3)).ok());
    ASSERT_TRUE(m.master->forward(unit, read_pdu(4)).ok());
    const auto& writes = m.line->writes();
    ASSERT_EQ(writes.size(), 4u);
    const auto t3_5 = codec::CharacterTiming{19200, 11}.t3_5();
    EXPECT_EQ(writes[1] - writes[0], latency + t3_5);          // on time: the silence kept anyway
    EXPECT_EQ(writes[2] - writes[1], 1s + 200ms);              // after the timeout: the window
    EXPECT_EQ(writes[3] - writes[2], latency + t3_5);          // on time again
}

// A late reply names its unit: a request to another unit cannot take it, so it need not wait,
// and a dead unit costs the others no more than its timeouts.
TEST(StrayReplies, ARequestToAnotherUnitDoesNotWaitForTheWindow) {
    TracedMaster m([](TimedLine& line, ByteView request, Instant at, unsigned n) {
        if (n == 0) return;  // unit 1 says nothing
        line.arrive(at + latency, codec::rtu_encode(request[0], reply_pdu(read_be16(request, 2))));
    });
    ASSERT_FALSE(m.master->forward(1, read_pdu(5)).ok());
    auto other = m.master->forward(2, read_pdu(6));
    ASSERT_TRUE(other.ok()) << other.error().message;
    EXPECT_EQ(to_hex(*other), to_hex(reply_pdu(6)));
    ASSERT_TRUE(m.master->forward(1, read_pdu(7)).ok());
    const auto& writes = m.line->writes();
    ASSERT_EQ(writes.size(), 3u);
    const auto t3_5 = codec::CharacterTiming{19200, 11}.t3_5();
    EXPECT_EQ(writes[1] - writes[0], 1s + t3_5);  // unit 2 at once
    // Unit 1 again: the window (1 s) since its try ended has passed already, less the 5 ms
    // unit 2 took and its silence; the rest is waited.
    EXPECT_GE(writes[2] - writes[0], 2s);
    EXPECT_LT(writes[2] - writes[0], 2s + 1ms);  // virtual time: streams wait in whole milliseconds
}

// Modbus has no transaction id on a serial line: a duplicate of the previous reply that lands
// after the next request was sent and before its real reply has that reply's shape. It has the
// bytes of a frame heard for another request, so it is refused, and the real reply after it
// taken.
TEST(StrayReplies, ADuplicateThatRacesTheRealReplyIsRefusedAndTheRealOneTaken) {
    Bytes previous_reply;
    TracedMaster m([&previous_reply](TimedLine& line, ByteView request, Instant at, unsigned n) {
        if (n == 3) line.arrive(at + 1ms, previous_reply);  // a repeater sends the last reply again
        previous_reply = reply_frame_to(request);
        line.arrive(at + latency, previous_reply);
    });
    for (const std::uint16_t address : {std::uint16_t{10}, std::uint16_t{11}, std::uint16_t{12}}) {
        auto reply = m.master->forward(unit, read_pdu(address));
        ASSERT_TRUE(reply.ok()) << reply.error().message;
        EXPECT_EQ(to_hex(*reply), to_hex(reply_pdu(address)));
    }
    auto raced = m.master->forward(unit, read_pdu(777));
    ASSERT_TRUE(raced.ok()) << raced.error().message;
    EXPECT_EQ(to_hex(*raced), to_hex(reply_pdu(777)));
    EXPECT_EQ(m.discarded_with("a copy, possibly"), 1u);
    EXPECT_EQ(m.line->writes().size(), 4u) << "the real reply came in the same try";
}

// A copy long after its original (a relay 350 ms late, with dozens of other requests answered
// in between) is known by its bytes all the same: the master keeps what it heard for the whole
// copy window, not a count of frames.
TEST(StrayReplies, ACopyHundredsOfFramesLateIsStillKnownForOne) {
    Bytes first_reply;
    TracedMaster m([&first_reply](TimedLine& line, ByteView request, Instant at, unsigned n) {
        const Bytes real = reply_frame_to(request);
        if (n == 0) first_reply = real;
        if (n == 200) {
            line.arrive(at + latency, first_reply);  // the real reply is lost; the copy comes on time
            return;
        }
        line.arrive(at + latency, real);
    });
    for (std::uint16_t address = 100; address < 300; ++address) ASSERT_TRUE(m.master->forward(unit, read_pdu(address)).ok());
    auto copied = m.master->forward(unit, read_pdu(300));
    ASSERT_TRUE(copied.ok()) << copied.error().message;
    EXPECT_EQ(to_hex(*copied), to_hex(reply_pdu(300))) << "the copy of register 100's reply was taken";
    EXPECT_EQ(m.discarded_with("a copy, possibly"), 1u);
}

// On a line that behaves a reply is handed out as soon as it is complete and checked: a frame
// after it belongs to the time between exchanges, heard out before the next request. Once the
// line has shown a fault, a second frame inside the silence after a reply makes it ambiguous
// (the first frame might have been the stray one), for as long as the fault may echo.
TEST(StrayReplies, ASecondFrameInsideTheSilenceMakesAReplyAmbiguousOnlyAfterAFault) {
    TracedMaster m(
        [](TimedLine& line, ByteView request, Instant at, unsigned n) {
            line.arrive(at + latency, reply_frame_to(request));
            if (n >= 1) line.arrive(at + latency + 1ms, codec::rtu_encode(unit, reply_pdu(static_cast<std::uint16_t>(900 + n))));
        },
        200ms);
    ASSERT_TRUE(m.master->forward(unit, read_pdu(5)).ok());
    auto at_once = m.master->forward(unit, read_pdu(6));
    ASSERT_TRUE(at_once.ok()) << at_once.error().message;
    EXPECT_EQ(to_hex(*at_once), to_hex(reply_pdu(6)));
    EXPECT_LT(m.clock->now() - m.line->writes().back(), latency + 1ms) << "handed out before the second frame came";
    // The second frame is heard out before the next request: a fault, and for the late-reply
    // window the line is careful.
    auto doubled = m.master->forward(unit, read_pdu(7));
    EXPECT_EQ(m.discarded_with("late reply from unit 1"), 1u);
    ASSERT_FALSE(doubled.ok()) << "took " << to_hex(*doubled);
    EXPECT_NE(doubled.error().message.find("another frame from unit 1"), std::string::npos) << doubled.error().message;
}

// When the stray reply differs in shape (a read of two registers while one is asked for), it is
// refused on its shape, and the real reply after it is taken.
TEST(StrayReplies, AStrayReplyOfAnotherShapeIsRefusedAndTheRealOneTaken) {
    TracedMaster m([](TimedLine& line, ByteView request, Instant at, unsigned n) {
        if (n == 1) line.arrive(at + 1ms, codec::rtu_encode(unit, reply_pdu(20, 2)));  // the other client's reply
        line.arrive(at + latency, reply_frame_to(request));
    });
    ASSERT_TRUE(m.master->forward(unit, read_pdu(1)).ok());
    auto reply = m.master->forward(unit, read_pdu(777));
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(to_hex(*reply), to_hex(reply_pdu(777)));
    EXPECT_EQ(m.discarded_with("byte count 4, the request asked for 2 bytes"), 1u);
}

// A reply cut short (the device reset mid-frame) is not a reply: after the timeout it is a
// request that got none, and the line is left to fall quiet before the next.
TEST(StrayReplies, ATruncatedReplyIsNoReply) {
    TracedMaster m([](TimedLine& line, ByteView request, Instant at, unsigned n) {
        Bytes frame = reply_frame_to(request);
        if (n == 0) frame.resize(4);
        line.arrive(at + latency, frame);
    });
    auto cut = m.master->forward(unit, read_pdu(1));
    ASSERT_FALSE(cut.ok());
    EXPECT_EQ(cut.error().kind, ErrorKind::timeout);
    auto next = m.master->forward(unit, read_pdu(2));
    ASSERT_TRUE(next.ok()) << next.error().message;
    EXPECT_EQ(to_hex(*next), to_hex(reply_pdu(2)));
}

// A retry asks the same again: the first try's late reply answers it as well as the second's
// would, so two frames there are no ambiguity.
TEST(StrayReplies, ALateReplyToAnEarlierTryOfTheSameRequestIsTaken) {
    auto clock = std::make_shared<VirtualClock>();
    unsigned requests = 0;
    // The first try's reply comes 3 ms after its timeout, just after the retry left; the
    // retry's own 2 ms after that, inside the silence after the first: two frames, one request.
    auto stream = std::make_unique<TimedLine>(clock, [&requests](TimedLine& line, ByteView request, Instant at) {
        line.arrive(at + (requests++ == 0 ? 1003ms : 2ms), reply_frame_to(request));
    });
    MasterOptions options;
    options.timeout = 1s;
    options.retries = 1;
    options.clock = clock;
    auto master = make_serial_master(std::move(stream), rtu_link(), options);
    auto reply = master->forward(unit, read_pdu(9));
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(to_hex(*reply), to_hex(reply_pdu(9)));
}

// A copy of the last reply that comes just when this reply is due, with the real reply 20 ms
// behind it (a loaded host, a USB adapter's latency timer): the copy is refused and the real
// reply awaited past its usual time by the host's jitter, and taken.
TEST(StrayReplies, ACopyOnTimeWithTheRealReplyALittleLateIsRefusedAndTheRealOneTaken) {
    Bytes previous_reply;
    TracedMaster m([&previous_reply](TimedLine& line, ByteView request, Instant at, unsigned n) {
        const Bytes real = reply_frame_to(request);
        if (n == 3) {
            line.arrive(at + latency, previous_reply);
            line.arrive(at + latency + 20ms, real);
        } else {
            line.arrive(at + latency, real);
        }
        previous_reply = real;
    });
    for (const std::uint16_t address : {std::uint16_t{10}, std::uint16_t{11}, std::uint16_t{12}}) {
        ASSERT_TRUE(m.master->forward(unit, read_pdu(address)).ok());
    }
    auto raced = m.master->forward(unit, read_pdu(777));
    ASSERT_TRUE(raced.ok()) << raced.error().message;
    EXPECT_EQ(to_hex(*raced), to_hex(reply_pdu(777)));
    EXPECT_EQ(m.discarded_with("a copy, possibly"), 1u);
    // While the fault may echo a reply is held for the silence after its usual time, and no more.
    const auto before = m.clock->now();
    ASSERT_TRUE(m.master->forward(unit, read_pdu(779)).ok());
    EXPECT_LT(m.clock->now() - before, latency + 5ms);
}

// A client's read-modify-write: it reads a register, writes it, and reads it back. The read-back's
// real reply is spoiled on the line, and a repeater's copy of the first read's reply comes just
// after: the same request's bytes, but from before the write, so the value it carries is the one
// the write replaced. Not taken (the soak, tests/gateway/line_soak_test.cpp, found a client
// reading back its old value). Without the write in between, the copy answers the read as well
// as the real reply would, and is taken.
TEST(StrayReplies, ACopyOfTheReplyBeforeAWriteIsNotTakenForTheSameReadAfterIt) {
    for (const bool written : {true, false}) {
        Bytes first_reply;
        TracedMaster m([&first_reply](TimedLine& line, ByteView request, Instant at, unsigned n) {
            if (request[1] == 0x06) return line.arrive(at + latency, Bytes(request.begin(), request.end()));  // the echo
            const Bytes real = reply_frame_to(request);
            if (n == 3) first_reply = real;
            if (n >= 4) {  // the read-back
                line.arrive(at + latency, Bytes{0x5b, 0xaf, 0x13, 0xf2, 0x2f, 0xac, 0x19});  // the real reply, garbled
                line.arrive(at + latency + 3ms, first_reply);                                 // the copy
                return;
            }
            line.arrive(at + latency, real);
        });
        for (const std::uint16_t address : {std::uint16_t{10}, std::uint16_t{11}, std::uint16_t{12}, std::uint16_t{777}}) {
            ASSERT_TRUE(m.master->forward(unit, read_pdu(address)).ok());
        }
        if (written) {
            Bytes write{0x06};
            append_be16(write, 777);
            append_be16(write, 5);
            ASSERT_TRUE(m.master->forward(unit, write).ok());
        }
        auto read_back = m.master->forward(unit, read_pdu(777));
        if (written) {
            ASSERT_FALSE(read_back.ok()) << "took " << to_hex(*read_back) << ", the value from before the write";
            EXPECT_EQ(read_back.error().kind, ErrorKind::mismatch);
            // Refused on the try the master adds for it too: that try's wait was not clean either
            // (the second time as a copy of the first try's frame, heard for no request).
            EXPECT_EQ(m.discarded_with("the value the write replaced"), 1u);
            EXPECT_EQ(m.discarded_with("a copy, possibly"), 1u);
        } else {
            ASSERT_TRUE(read_back.ok()) << read_back.error().message;
            EXPECT_EQ(to_hex(*read_back), to_hex(reply_pdu(777)));
        }
    }
}

// The same read-modify-write on a clean line: the read-back's real reply comes late (after the
// timeout) and the copy of the first read's reply on time, alone, where the real reply was due.
// Nothing in the wait tells it from the reply but the write in between: it is refused, the
// read tried again once the late reply has passed, and the new value taken (the soak found a
// client reading back its old value so). A write elsewhere leaves the read's reply the same, and
// it is taken at once; a write of the value there already makes the device answer the same
// bytes, taken when the next try hears them again: a try the master adds for it, beyond
// `retries` (none here), so that it costs a wait, not a failed read.
TEST(StrayReplies, AReplyFromBeforeAWriteOverTheReadIsTakenOnlyWhenHeardAgainAfterIt) {
    const Bytes new_value{0x03, 0x02, 0x00, 0x05};
    enum Write { over_the_read, elsewhere, same_value };
    for (const Write write : {over_the_read, elsewhere, same_value}) {
        SCOPED_TRACE(write == over_the_read ? "a write over the read" : write == elsewhere ? "a write elsewhere" : "a write of the same value");
        Bytes first_reply;
        TracedMaster m([&](TimedLine& line, ByteView request, Instant at, unsigned n) {
            if (request[1] == 0x06) return line.arrive(at + latency, Bytes(request.begin(), request.end()));  // the echo
            if (n == 0) first_reply = reply_frame_to(request);
            if (n == 2 && write == over_the_read) {  // the read-back's first try
                line.arrive(at + 1500ms, codec::rtu_encode(unit, new_value));  // the real reply, late
                line.arrive(at + latency, first_reply);                         // the copy, on time
                return;
            }
            line.arrive(at + latency, n >= 2 && write == over_the_read ? codec::rtu_encode(unit, new_value) : reply_frame_to(request));
        });
        ASSERT_TRUE(m.master->forward(unit, read_pdu(777)).ok());
        Bytes written{0x06};
        append_be16(written, write == elsewhere ? 900 : 777);
        append_be16(written, write == over_the_read ? 5 : value_at(777));
        ASSERT_TRUE(m.master->forward(unit, written).ok());
        auto read_back = m.master->forward(unit, read_pdu(777));
        ASSERT_TRUE(read_back.ok()) << read_back.error().message;
        EXPECT_EQ(to_hex(*read_back), to_hex(write == over_the_read ? new_value : reply_pdu(777)));
        EXPECT_EQ(m.discarded_with("the value the write replaced"), write == elsewhere ? 0u : 1u);
        EXPECT_EQ(m.line->writes().size(), write == elsewhere ? 3u : 4u) << "the read-back is tried again unless the write was elsewhere";
    }
}

// A write asked again (a restore that retries, a client that writes the same set point twice)
// is echoed with the same bytes as the first time, whatever the device held: the echo is its
// answer, not a copy of a value the write replaced, even after a damaged frame in the wait
// (the AC20's restore on a faulty bus failed every second write so).
TEST(StrayReplies, AWriteAskedAgainTakesItsEchoThoughItEqualsTheFirst) {
    TracedMaster m([](TimedLine& line, ByteView request, Instant at, unsigned n) {
        if (n == 1) line.arrive(at + latency, Bytes{0x5b, 0xaf, 0x13});  // noise before the echo
        line.arrive(at + latency + 3ms, Bytes(request.begin(), request.end()));
    });
    Bytes written{0x05};
    append_be16(written, 218);
    append_be16(written, 0xFF00);
    ASSERT_TRUE(m.master->forward(unit, written).ok());
    auto again = m.master->forward(unit, written);
    ASSERT_TRUE(again.ok()) << again.error().message;
    EXPECT_EQ(*again, written);
    EXPECT_EQ(m.line->writes().size(), 2u);
}

// Registers that really hold the same value answer with the same bytes: the second looks like a
// copy of the first and is refused, and the request is asked once more, beyond `retries` (none
// here). The device says the same again in a clean wait: its own answer, taken. A failed read
// would cost more than the try.
TEST(StrayReplies, RegistersHoldingTheSameValueCostOneMoreTryNotAFailure) {
    const Bytes zero_pdu{0x03, 0x02, 0x00, 0x00};  // every register holds 0: every reply is alike
    TracedMaster m([&zero_pdu](TimedLine& line, ByteView, Instant at, unsigned) {
        line.arrive(at + latency, codec::rtu_encode(unit, zero_pdu));
    });
    for (const std::uint16_t address : {std::uint16_t{10}, std::uint16_t{11}, std::uint16_t{12}, std::uint16_t{13}}) {
        auto reply = m.master->forward(unit, read_pdu(address));
        ASSERT_TRUE(reply.ok()) << reply.error().message;
        EXPECT_EQ(*reply, zero_pdu);
    }
    EXPECT_EQ(m.discarded_with("a copy, possibly"), 3u);
    EXPECT_EQ(m.line->writes().size(), 7u) << "each read after the first is asked twice";
    // The same read again answers as it did: no copy to refuse, one try.
    ASSERT_TRUE(m.master->forward(unit, read_pdu(13)).ok());
    EXPECT_EQ(m.line->writes().size(), 8u);
    // A poll after the copy window finds its own last answer again (kept until a write over it):
    // one try, though the other registers' replies were heard with the same bytes since.
    m.clock->sleep_for(5s);
    ASSERT_TRUE(m.master->forward(unit, read_pdu(10)).ok());
    ASSERT_TRUE(m.master->forward(unit, read_pdu(12)).ok());
    EXPECT_EQ(m.line->writes().size(), 10u);
}

// A copy that comes on time in place of a reply that is lost (a repeater's copy of the reply
// before) is refused, however long the line has behaved, and the request asked again: the
// device's real answer is taken, not register 12's value.
TEST(StrayReplies, ACopyOnTimeInPlaceOfALostReplyIsRefusedAndTheRequestAskedAgain) {
    Bytes previous_reply;
    TracedMaster m([&previous_reply](TimedLine& line, ByteView request, Instant at, unsigned n) {
        const Bytes real = reply_frame_to(request);
        if (n == 3) {
            line.arrive(at + latency, previous_reply);  // the real reply is lost
        } else {
            line.arrive(at + latency, real);
            previous_reply = real;
        }
    });
    for (const std::uint16_t address : {std::uint16_t{10}, std::uint16_t{11}, std::uint16_t{12}}) {
        ASSERT_TRUE(m.master->forward(unit, read_pdu(address)).ok());
    }
    auto copied = m.master->forward(unit, read_pdu(30));
    ASSERT_TRUE(copied.ok()) << copied.error().message;
    EXPECT_EQ(to_hex(*copied), to_hex(reply_pdu(30))) << "took register 12's value for register 30";
    EXPECT_EQ(m.discarded_with("a copy, possibly"), 1u);
}

// A copy of unit 1's reply heard in unit 2's exchange, and another on time in place of a reply
// to unit 1 that is lost: both refused, and unit 1's real value taken on the next try.
TEST(StrayReplies, ACopyInAnotherUnitsExchangeAndOneInPlaceOfALostReplyAreRefused) {
    Bytes previous_reply;
    TracedMaster m([&previous_reply](TimedLine& line, ByteView request, Instant at, unsigned n) {
        const std::uint8_t asked = request[0];
        const Bytes real = codec::rtu_encode(asked, reply_pdu(read_be16(request, 2), read_be16(request, 4)));
        if (n == 2) {
            line.arrive(at + latency, previous_reply);  // unit 1's real reply is lost
            return;
        }
        if (n == 1) line.arrive(at + 1ms, previous_reply);  // in unit 2's exchange
        line.arrive(at + latency, real);
        if (asked == unit) previous_reply = real;
    });
    ASSERT_TRUE(m.master->forward(unit, read_pdu(10)).ok());
    auto other = m.master->forward(2, read_pdu(50));
    ASSERT_TRUE(other.ok()) << other.error().message;
    EXPECT_EQ(to_hex(*other), to_hex(reply_pdu(50)));
    auto copied = m.master->forward(unit, read_pdu(30));
    ASSERT_TRUE(copied.ok()) << copied.error().message;
    EXPECT_EQ(to_hex(*copied), to_hex(reply_pdu(30))) << "took register 10's value for register 30";
    EXPECT_EQ(m.discarded_with("a copy, possibly"), 1u);
}

// A late reply to a request that timed out is heard out before the next request and kept in
// mind: a later frame with its bytes is refused as a possible copy, and taken when the device
// says it again (register 21 holds what register 11 holds).
TEST(StrayReplies, ALateReplyIsRememberedAndAnEqualValueTakenWhenSaidAgain) {
    TracedMaster m(
        [](TimedLine& line, ByteView request, Instant at, unsigned n) {
            const std::uint16_t address = read_be16(request, 2);
            const Bytes real = codec::rtu_encode(unit, reply_pdu(address == 21 ? 11 : address));
            line.arrive(at + (n == 1 ? 1050ms : latency), real);
        },
        100ms);
    ASSERT_TRUE(m.master->forward(unit, read_pdu(10)).ok());
    ASSERT_FALSE(m.master->forward(unit, read_pdu(10)).ok());  // its reply comes after the timeout
    ASSERT_TRUE(m.master->forward(unit, read_pdu(11)).ok());   // after the late reply, heard and dropped
    EXPECT_EQ(m.discarded_with("late reply from unit 1"), 1u);
    auto same_value = m.master->forward(unit, read_pdu(21));
    ASSERT_TRUE(same_value.ok()) << same_value.error().message;
    EXPECT_EQ(to_hex(*same_value), to_hex(reply_pdu(11)));
    EXPECT_EQ(m.discarded_with("a copy, possibly"), 1u);
}

// ---------------------------------------------------------------------------------------------
// Wall time, the virtual bus, a RegisterBank served by the slave, and random faults on its
// replies.

struct ReplyFaults {
    std::mt19937 random{20};
    std::map<std::string, unsigned> counts;
    std::mutex mutex;

    transport::BusFault decide(const std::string& from, ByteView bytes, std::chrono::milliseconds timeout) {
        transport::BusFault fault;
        if (from != "slave" || bytes.size() < 2) return fault;
        std::lock_guard lock(mutex);
        const unsigned roll = std::uniform_int_distribution<unsigned>(0, 99)(random);
        // Faults compound freely: a copy may come when a reply is due while that reply is late
        // (the copy rule knows it by its bytes).
        const auto anywhere = std::uniform_int_distribution<std::size_t>(0, bytes.size() - 1)(random);
        if (roll < 7) {
            fault.extra_delay = timeout + std::chrono::milliseconds(std::uniform_int_distribution<int>(5, 40)(random));
            ++counts["late"];
        } else if (roll < 14) {
            fault.duplicate_after = std::chrono::milliseconds(std::uniform_int_distribution<int>(1, 40)(random));
            ++counts["duplicated"];
        } else if (roll < 18) {
            fault.truncate_to = std::uniform_int_distribution<std::size_t>(1, bytes.size() - 1)(random);
            ++counts["truncated"];
        } else if (roll < 22) {
            fault.corrupt_bytes = {anywhere};
            ++counts["bit flips"];
        } else if (roll < 25) {
            fault.noise_before = Bytes{0x01, 0x03, 0x02, static_cast<std::uint8_t>(roll)};
            ++counts["garbage before"];
        }
        return fault;
    }
};

TEST(StrayReplies, NeverReturnsAWrongPduUnderLateDuplicatedTruncatedCorruptedOrNoisyReplies) {
    const auto link = *transport::parse_link_url("rtu:virtual?baud=38400&parity=none");
    auto bus = transport::VirtualBus::create(38400, 10);
    auto faults = std::make_shared<ReplyFaults>();
    constexpr auto timeout = 60ms;
    bus->set_fault_injector(
        [faults](const std::string& from, ByteView bytes) { return faults->decide(from, bytes, timeout); });
    auto bank = std::make_shared<RegisterBank>();
    for (std::uint16_t address = 0; address < 64; ++address) bank->set(codec::Table::holding_registers, address, value_at(address));
    Slave slave(link, {{unit, bank}});
    auto slave_port = bus->attach("slave");
    std::jthread server([&](std::stop_token stop) { (void)slave.serve_stream(*slave_port, stop); });

    MasterOptions options;
    options.timeout = timeout;
    std::mutex trace_mutex;
    std::vector<std::string> trace;
    const auto t0 = std::chrono::steady_clock::now();
    options.trace = [&](const TraceEvent& event) {
        std::lock_guard lock(trace_mutex);
        trace.push_back(fmt::format("{:8.3f} {} {} {}", std::chrono::duration<double, std::milli>(event.at - t0).count(),
                                    static_cast<int>(event.direction), to_hex(event.bytes), event.note));
    };
    auto master = make_serial_master(bus->attach("master"), link, options);

    unsigned right = 0;
    std::map<std::string, unsigned> failures;
    std::vector<std::string> wrong;
    for (unsigned i = 0; i < 250; ++i) {
        // Mostly one-register reads of distinct registers (the hard case: every reply has the
        // same shape), some of two registers.
        const auto address = static_cast<std::uint16_t>(i % 63);
        const std::uint16_t count = i % 5 == 4 ? 2 : 1;
        auto reply = master->forward(unit, read_pdu(address, count));
        if (!reply.ok()) {
            ++failures[reply.error().kind == ErrorKind::timeout ? "timeout" : "bad reply"];
        } else if (*reply == reply_pdu(address, count)) {
            ++right;
        } else {
            wrong.push_back(fmt::format("read {} x{}: got {}", address, count, to_hex(*reply)));
            std::lock_guard lock(trace_mutex);
            for (std::size_t k = trace.size() > 14 ? trace.size() - 14 : 0; k < trace.size(); ++k) std::cout << trace[k] << "\n";
            std::cout << "----\n";
        }
    }
    std::string faults_seen;
    std::string failures_seen;
    for (const auto& [kind, n] : faults->counts) faults_seen += fmt::format(" {} {}", kind, n);
    for (const auto& [kind, n] : failures) failures_seen += fmt::format(" {} {}", kind, n);
    std::cout << fmt::format("250 requests: {} right, {} wrong; failed:{}; faults:{}\n", right, wrong.size(),
                             failures_seen, faults_seen);
    EXPECT_TRUE(wrong.empty()) << wrong.size() << " wrong, first: " << wrong.front();
    for (const char* kind : {"late", "duplicated", "truncated", "bit flips", "garbage before"}) {
        EXPECT_GT(faults->counts[kind], 0u) << kind << " never happened";
    }
    EXPECT_GT(right, 125u);  // most requests still get through
}

}  // namespace
}  // namespace loopwire::session
