// The line scheduler: one request on the wire at a time, writes before clients' requests before
// polls, round robin between clients, requests past their deadline or whose asker has gone never
// sent, a silent unit's polls held back until its back-off is due (which only polls move), a
// scheduler that can go while a request is still out, and one handed over across a reload.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "common/never_sent.hpp"
#include "gateway/line_scheduler.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;

// Each test request reads the holding register numbered by its tag, so what went on the wire
// says which request it was.
Bytes pdu_for(int tag) {
    return Bytes{0x03, static_cast<std::uint8_t>(tag >> 8), static_cast<std::uint8_t>(tag & 0xFF), 0x00, 0x01};
}

int tag_of(const Bytes& pdu) { return (pdu.at(1) << 8) | pdu.at(2); }

Bytes normal_reply() { return Bytes{0x03, 0x02, 0x00, 0x2A}; }
Bytes exception_reply() { return Bytes{0x83, 0x02}; }
Error timed_out() { return make_error(ErrorKind::timeout, "no reply from the unit"); }

Result<codec::Reply> forward_only() { return make_error(ErrorKind::usage, "the fake master only forwards"); }

// A master the test answers by hand: forward_async records what was sent and holds the
// completion until complete(). Set `instant` and it answers inside forward_async instead.
class HandMaster final : public session::Master {
public:
    struct Sent {
        std::uint8_t unit;
        Bytes pdu;
    };

    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override { return forward_only(); }
    void execute_async(std::uint8_t, codec::Request, Completion done) override { done(forward_only()); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return make_error(ErrorKind::link, "not here"); }
    std::string describe() const override { return "hand master"; }

    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override {
        if (held_.size() >= capacity) {
            ADD_FAILURE() << "request " << tag_of(pdu) << " forwarded while " << held_.size() << " are on the wire";
        }
        sent_.push_back({unit, std::move(pdu)});
        if (!instant) {
            held_.push_back(std::move(done));
            return;
        }
        done(normal_reply());
    }

    // Answers the oldest request on the wire, as the master's thread would.
    void complete(Result<Bytes> result) {
        ASSERT_FALSE(held_.empty()) << "nothing on the wire to complete";
        auto done = std::move(held_.front());
        held_.pop_front();
        done(std::move(result));
    }

    bool waiting() const { return !held_.empty(); }
    std::size_t on_wire() const { return held_.size(); }

    std::vector<int> sent_tags() const {
        std::vector<int> tags;
        for (const auto& sent : sent_) tags.push_back(tag_of(sent.pdu));
        return tags;
    }

    std::vector<Sent> sent() const { return sent_; }

    bool instant = false;
    std::size_t capacity = 1;  // requests it takes at once (a Modbus TCP device: several)

private:
    std::vector<Sent> sent_;
    std::deque<ForwardCompletion> held_;  // oldest first
};

class LineSchedulerTest : public ::testing::Test {
protected:
    static LineSchedulerOptions backoff_options() {
        LineSchedulerOptions options;
        options.first_backoff = 1000ms;
        options.max_backoff = 30000ms;
        return options;
    }

    LineRequest ask(int tag, Priority priority = Priority::client, std::uint8_t unit = 1, std::uint64_t client = 0) {
        LineRequest request;
        request.unit = unit;
        request.pdu = pdu_for(tag);
        request.priority = priority;
        request.client = client;
        request.done = [this, tag](Result<Bytes> result) { answers[tag].push_back(std::move(result)); };
        return request;
    }

    void submit(int tag, Priority priority = Priority::client, std::uint8_t unit = 1, std::uint64_t client = 0) {
        scheduler->submit(ask(tag, priority, unit, client));
    }

    // Answers every request in turn until nothing is left on the wire.
    void complete_all() {
        while (master->waiting()) master->complete(normal_reply());
    }

    const Result<Bytes>& only_answer(int tag) {
        static const Result<Bytes> none = make_error(ErrorKind::usage, "no answer at all");
        EXPECT_EQ(answers[tag].size(), 1U) << "request " << tag;
        return answers[tag].empty() ? none : answers[tag].front();
    }

    bool was_sent(int tag) const {
        const auto tags = master->sent_tags();
        return std::find(tags.begin(), tags.end(), tag) != tags.end();
    }

    // Declared in this order so the scheduler goes first: its destructor still answers.
    std::shared_ptr<VirtualClock> clock = std::make_shared<VirtualClock>();
    std::shared_ptr<HandMaster> master = std::make_shared<HandMaster>();
    std::map<int, std::vector<Result<Bytes>>> answers;
    std::unique_ptr<LineScheduler> scheduler = std::make_unique<LineScheduler>(master, backoff_options(), clock);
};

// Utilisation: the time requests were on the line, against the time the line has been open.
TEST_F(LineSchedulerTest, CountsTheTimeTheLineCarriesRequests) {
    clock->sleep_for(5ms);
    submit(1);
    clock->sleep_for(12ms);
    master->complete(normal_reply());
    clock->sleep_for(20ms);
    submit(2);
    clock->sleep_for(3ms);
    master->complete(make_error(ErrorKind::timeout, "silence"));
    const auto stats = scheduler->statistics();
    EXPECT_EQ(stats.busy, 15ms);
    EXPECT_EQ(stats.open, 40ms);
}

TEST_F(LineSchedulerTest, SendsOneRequestAtATime) {
    for (int tag = 1; tag <= 5; ++tag) submit(tag);
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1}));
    EXPECT_EQ(scheduler->statistics().queued, 4U);

    for (int answered = 1; answered <= 5; ++answered) {
        ASSERT_EQ(master->sent_tags().size(), static_cast<std::size_t>(answered));
        EXPECT_TRUE(answers[answered].empty()) << "done before the reply";
        master->complete(normal_reply());
        EXPECT_EQ(only_answer(answered).value(), normal_reply());
    }
    EXPECT_FALSE(master->waiting());
    const auto stats = scheduler->statistics();
    EXPECT_EQ(stats.sent, 5U);
    EXPECT_EQ(stats.answered, 5U);
    EXPECT_EQ(stats.queued, 0U);
}

// A Modbus TCP line (max_in_flight > 1): requests go as they come up to the bound, the next one
// as soon as any is answered, in the same order of turns (a write first); the line counts as busy
// while at least one is out, not once per request.
TEST_F(LineSchedulerTest, PipelinedLineCarriesUpToMaxInFlightRequestsAtOnce) {
    auto options = backoff_options();
    options.max_in_flight = 3;
    master->capacity = 3;
    scheduler = std::make_unique<LineScheduler>(master, options, clock);

    for (int tag = 1; tag <= 5; ++tag) submit(tag, Priority::client, 1, static_cast<std::uint64_t>(tag));
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 2, 3}));
    auto stats = scheduler->statistics();
    EXPECT_EQ(stats.in_flight, 3U);
    EXPECT_EQ(stats.queued, 2U);

    submit(6, Priority::write);
    clock->sleep_for(10ms);
    master->complete(normal_reply());  // 1
    EXPECT_EQ(only_answer(1).value(), normal_reply());
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 2, 3, 6})) << "the write goes first";
    clock->sleep_for(10ms);
    master->complete(normal_reply());  // 2
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 2, 3, 6, 4}));
    complete_all();
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 2, 3, 6, 4, 5}));
    for (int tag = 1; tag <= 6; ++tag) EXPECT_TRUE(only_answer(tag).ok()) << tag;

    stats = scheduler->statistics();
    EXPECT_EQ(stats.sent, 6U);
    EXPECT_EQ(stats.answered, 6U);
    EXPECT_EQ(stats.in_flight, 0U);
    EXPECT_FALSE(stats.on_wire);
    EXPECT_EQ(stats.busy, 20ms) << "two requests out at once are 10 ms of line time, not 20";
}

TEST_F(LineSchedulerTest, WritesGoFirstThenClientRequestsAndPollsTakeTurns) {
    submit(1, Priority::poll);  // on the wire while the rest queue
    submit(2, Priority::poll);
    submit(3, Priority::client);
    submit(4, Priority::write);
    submit(5, Priority::poll);
    submit(6, Priority::client);
    submit(7, Priority::write);
    submit(8, Priority::client, 1, 2);
    complete_all();
    // A poll went last (1), so a client's request goes next; then turns (the clients round
    // robin among themselves), and the clients' requests left once the polls are done.
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 4, 7, 3, 2, 8, 5, 6}));
    EXPECT_EQ(scheduler->statistics().polls_sent, 3U);
}

// Turns count requests that went on the wire: a poll refused unsent (its unit backs off) is
// no turn, so the next poll still goes before the next client's request.
TEST_F(LineSchedulerTest, APollDroppedUnsentCostsThePollsNoTurn) {
    submit(1, Priority::poll, 5);
    master->complete(timed_out());  // unit 5 backs off
    submit(2, Priority::client);    // on the wire
    submit(3, Priority::client);
    submit(4, Priority::poll, 5);   // refused when its turn comes
    submit(5, Priority::poll, 6);
    complete_all();
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 2, 5, 3}));
    EXPECT_FALSE(only_answer(4).ok());
}

TEST_F(LineSchedulerTest, BusyClientDelaysAnotherByAtMostOneRequest) {
    const std::uint64_t busy = 1;
    const std::uint64_t other = 2;
    submit(0, Priority::client, 1, busy);  // on the wire
    for (int tag = 1; tag <= 100; ++tag) submit(tag, Priority::client, 1, busy);
    submit(1000, Priority::client, 1, other);
    complete_all();
    const auto tags = master->sent_tags();
    ASSERT_EQ(tags.size(), 102U);
    const auto position = std::find(tags.begin(), tags.end(), 1000) - tags.begin();
    EXPECT_LE(position, 2) << "the other client's request waited behind " << position - 1 << " of the busy one's";
    // The busy client's own requests keep their order.
    EXPECT_TRUE(std::is_sorted(tags.begin(), tags.begin() + position));
    EXPECT_TRUE(std::is_sorted(tags.begin() + position + 1, tags.end()));
}

// Most clients send their next request only once they have the reply, so they have nothing
// queued when the line frees. Such a client still gets every other turn against a busy one:
// its request waits for the one on the wire only (with a dead unit, one timeout, not two).
TEST_F(LineSchedulerTest, ClientAskingOneAtATimeWaitsOnlyForTheRequestOnTheWire) {
    const std::uint64_t busy = 1;
    const std::uint64_t one_at_a_time = 2;
    for (int tag = 1; tag <= 10; ++tag) submit(tag, Priority::client, 1, busy);  // 1 on the wire
    master->complete(normal_reply());  // 2 on the wire
    for (int round = 0; round < 4; ++round) {
        submit(100 + round, Priority::client, 1, one_at_a_time);  // while one of the busy's is on the wire
        master->complete(normal_reply());
        EXPECT_EQ(master->sent_tags().back(), 100 + round)
            << "round " << round << ": waited behind another of the busy's";
        master->complete(normal_reply());  // the reply; the busy client's next goes on the wire
    }
    complete_all();
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 2, 100, 3, 101, 4, 102, 5, 103, 6, 7, 8, 9, 10}));
}

TEST_F(LineSchedulerTest, ClientsTakeTurnsWithinWritesToo) {
    submit(0, Priority::poll);  // on the wire
    for (int tag : {11, 12, 13}) submit(tag, Priority::write, 1, 1);
    for (int tag : {21, 22, 23}) submit(tag, Priority::write, 1, 2);
    submit(31, Priority::write, 1, 3);
    complete_all();
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{0, 11, 21, 31, 12, 22, 13, 23}));
}

TEST_F(LineSchedulerTest, RequestPastItsDeadlineIsNeverSent) {
    submit(1);  // on the wire
    auto late = ask(2);
    late.deadline = clock->now() + 1s;
    scheduler->submit(std::move(late));
    auto in_time = ask(3);
    in_time.deadline = clock->now() + 10s;
    scheduler->submit(std::move(in_time));

    clock->advance(2s);
    complete_all();

    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 3}));
    const auto& expired = only_answer(2);
    ASSERT_FALSE(expired.ok());
    EXPECT_EQ(expired.error().kind, ErrorKind::timeout);
    EXPECT_TRUE(never_sent(expired.error())) << "a poll that expired here says nothing of its device";
    EXPECT_NE(expired.error().message.find("deadline passed before the line was free"), std::string::npos)
        << expired.error().message;
    EXPECT_TRUE(only_answer(3).ok());
    EXPECT_EQ(scheduler->statistics().expired, 1U);
    EXPECT_EQ(scheduler->statistics().sent, 2U);
}

TEST_F(LineSchedulerTest, RequestWhoseAskerHasGoneIsNeverSent) {
    submit(1);  // on the wire
    auto asker_here = std::make_shared<std::atomic<bool>>(true);
    auto gone = ask(2);
    gone.still_wanted = asker_here;
    scheduler->submit(std::move(gone));
    auto wanted = ask(3);
    wanted.still_wanted = std::make_shared<std::atomic<bool>>(true);
    scheduler->submit(std::move(wanted));

    *asker_here = false;  // the client disconnected while its request queued
    complete_all();

    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 3}));
    const auto& abandoned = only_answer(2);
    ASSERT_FALSE(abandoned.ok());
    EXPECT_EQ(abandoned.error().kind, ErrorKind::link);
    EXPECT_NE(abandoned.error().message.find("the asker has gone"), std::string::npos);
    EXPECT_EQ(scheduler->statistics().abandoned, 1U);
}

TEST_F(LineSchedulerTest, SilentUnitsPollsWaitForItsBackOffWhileOthersGoOn) {
    submit(1, Priority::poll, 5);
    master->complete(timed_out());
    EXPECT_EQ(scheduler->statistics().timeouts, 1U);

    submit(2, Priority::poll, 5);  // refused at once: the line is free but unit 5 backs off
    EXPECT_FALSE(was_sent(2));
    const auto& refused = only_answer(2);
    ASSERT_FALSE(refused.ok());
    EXPECT_EQ(refused.error().kind, ErrorKind::timeout);
    EXPECT_NE(refused.error().message.find("backing off after 1 consecutive timeout"), std::string::npos)
        << refused.error().message;
    EXPECT_NE(refused.error().message.find("1000 ms"), std::string::npos) << refused.error().message;

    submit(3, Priority::poll, 6);  // another unit is polled as usual
    EXPECT_TRUE(was_sent(3));
    master->complete(normal_reply());

    clock->advance(999ms);
    submit(4, Priority::poll, 5);
    EXPECT_FALSE(was_sent(4));

    clock->advance(1ms);  // the back-off is due: this poll is the probe
    submit(5, Priority::poll, 5);
    EXPECT_TRUE(was_sent(5));
    master->complete(timed_out());  // still silent: the wait doubles

    clock->advance(1999ms);
    submit(6, Priority::poll, 5);
    EXPECT_FALSE(was_sent(6));
    EXPECT_NE(only_answer(6).error().message.find("after 2 consecutive timeouts"), std::string::npos);

    clock->advance(1ms);
    submit(7, Priority::poll, 5);
    EXPECT_TRUE(was_sent(7));
    master->complete(exception_reply());  // an exception reply is an answer: the unit is back

    submit(8, Priority::poll, 5);
    EXPECT_TRUE(was_sent(8));
    master->complete(normal_reply());

    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 3, 5, 7, 8}));
    const auto stats = scheduler->statistics();
    EXPECT_EQ(stats.backed_off, 3U);
    EXPECT_EQ(stats.timeouts, 2U);
    EXPECT_EQ(stats.answered, 3U);
    EXPECT_EQ(stats.sent, 5U);
}

TEST_F(LineSchedulerTest, ClientRequestsToABackingOffUnitAreStillSentAndDoNotMoveItsBackOff) {
    submit(1, Priority::poll, 5);
    master->complete(timed_out());

    submit(2, Priority::client, 5);
    EXPECT_TRUE(was_sent(2));
    master->complete(timed_out());
    submit(3, Priority::write, 5);
    EXPECT_TRUE(was_sent(3));
    master->complete(normal_reply());  // the unit answers a write: only a poll's answer ends a back-off

    submit(4, Priority::poll, 5);
    EXPECT_FALSE(was_sent(4));
    clock->advance(1s);  // still the first 1 s: neither the client's timeout nor the write moved it
    submit(5, Priority::poll, 5);
    EXPECT_TRUE(was_sent(5));
    master->complete(normal_reply());
    EXPECT_EQ(scheduler->statistics().backed_off, 1U);
    EXPECT_EQ(scheduler->statistics().timeouts, 2U);
}

// The field's case: a client sends a request the unit ignores (a 253-byte PDU longer than its
// buffer). The client gets its timeout (0Bh at the front); the unit's polls go on as before,
// so its status stays what its polls find.
TEST_F(LineSchedulerTest, ClientAndWriteTimeoutsAreCountedButDoNotBackTheUnitOff) {
    submit(1, Priority::client, 5);
    master->complete(timed_out());
    submit(2, Priority::write, 5);
    master->complete(timed_out());
    EXPECT_EQ(scheduler->hold_poll(5), std::nullopt);

    submit(3, Priority::poll, 5);  // at once, with no time passed
    EXPECT_TRUE(was_sent(3));
    master->complete(normal_reply());
    EXPECT_TRUE(only_answer(3).ok());
    EXPECT_FALSE(only_answer(1).ok());
    EXPECT_EQ(only_answer(1).error().kind, ErrorKind::timeout);
    const auto stats = scheduler->statistics();
    EXPECT_EQ(stats.timeouts, 2U);
    EXPECT_EQ(stats.backed_off, 0U);
}

// The poller asks before each poll, and keeps no back-off of its own: the times it is told are
// the scheduler's 1 s, 2 s, 4 s ... and each poll held back is counted.
TEST_F(LineSchedulerTest, HoldPollTellsThePollerWhenTheUnitsNextPollMayGo) {
    const Instant start = clock->now();
    EXPECT_EQ(scheduler->hold_poll(5), std::nullopt);
    submit(1, Priority::poll, 5);
    master->complete(timed_out());
    EXPECT_EQ(scheduler->hold_poll(5), start + 1s);
    EXPECT_EQ(scheduler->hold_poll(6), std::nullopt) << "another unit is held back too";
    clock->advance(1s);
    EXPECT_EQ(scheduler->hold_poll(5), std::nullopt);
    submit(2, Priority::poll, 5);
    master->complete(timed_out());
    EXPECT_EQ(scheduler->hold_poll(5), start + 3s);
    clock->advance(2s);
    submit(3, Priority::poll, 5);
    master->complete(timed_out());
    EXPECT_EQ(scheduler->hold_poll(5), start + 7s);
    EXPECT_EQ(scheduler->statistics().backed_off, 3U);
}

// A link failure (the line went down, reopening_master.hpp) says the silences before may have
// been the line's: once it is back, every unit is polled at once.
TEST_F(LineSchedulerTest, ALinkFailureEndsEveryUnitsBackOff) {
    submit(1, Priority::poll, 5);
    master->complete(timed_out());
    submit(2, Priority::poll, 6);
    master->complete(timed_out());
    ASSERT_TRUE(scheduler->hold_poll(5).has_value());
    submit(3, Priority::client, 7);
    master->complete(make_error(ErrorKind::link, "line plant (rtu:/dev/ttyUSB0) is down: hung up; retrying in 1 s"));
    EXPECT_EQ(scheduler->hold_poll(5), std::nullopt);
    EXPECT_EQ(scheduler->hold_poll(6), std::nullopt);
}

TEST_F(LineSchedulerTest, BadRepliesAreCountedAndDoNotBackOff) {
    submit(1, Priority::poll, 5);
    master->complete(make_error(ErrorKind::mismatch, "reply for another function"));
    submit(2, Priority::poll, 5);
    master->complete(make_error(ErrorKind::malformed, "bad CRC"));
    submit(3, Priority::poll, 5);
    EXPECT_TRUE(was_sent(3));
    master->complete(make_error(ErrorKind::link, "port gone"));
    const auto stats = scheduler->statistics();
    EXPECT_EQ(stats.bad_replies, 2U);
    EXPECT_EQ(stats.answered, 0U);
    EXPECT_EQ(stats.timeouts, 0U);
    EXPECT_EQ(stats.sent, 3U);
    EXPECT_EQ(only_answer(3).error().kind, ErrorKind::link);
}

TEST_F(LineSchedulerTest, DoneMaySubmitAgain) {
    auto first = ask(1);
    first.done = [this](Result<Bytes> result) {
        answers[1].push_back(std::move(result));
        submit(2);  // from the completion, as a client that asks again would
    };
    scheduler->submit(std::move(first));
    master->complete(normal_reply());
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 2}));
    master->complete(normal_reply());
    EXPECT_TRUE(only_answer(2).ok());
}

TEST_F(LineSchedulerTest, MasterAnsweringAtOnceDoesNotRecurse) {
    submit(0);  // held on the wire while a long queue builds
    constexpr int queued = 50000;
    for (int tag = 1; tag <= queued; ++tag) submit(tag, Priority::poll);
    master->instant = true;
    master->complete(normal_reply());  // each further reply comes inside forward_async
    EXPECT_EQ(master->sent_tags().size(), static_cast<std::size_t>(queued + 1));
    EXPECT_EQ(scheduler->statistics().answered, static_cast<std::uint64_t>(queued + 1));
    EXPECT_EQ(answers.size(), static_cast<std::size_t>(queued + 1));
}

TEST_F(LineSchedulerTest, DoneSubmittingToAMasterAnsweringAtOnceIsALoop) {
    master->instant = true;
    constexpr int chain = 20000;
    std::function<void(int)> ask_from = [&](int tag) {
        auto request = ask(tag);
        request.done = [&, tag](Result<Bytes> result) {
            answers[tag].push_back(std::move(result));
            if (tag < chain) ask_from(tag + 1);
        };
        scheduler->submit(std::move(request));
    };
    ask_from(1);
    EXPECT_EQ(answers.size(), static_cast<std::size_t>(chain));
    EXPECT_EQ(scheduler->statistics().sent, static_cast<std::uint64_t>(chain));
}

TEST_F(LineSchedulerTest, DestroyingFailsWhatIsQueuedAndALateReplyIsHarmless) {
    submit(1);  // on the wire
    submit(2, Priority::poll);
    submit(3, Priority::client);
    submit(4, Priority::write);
    scheduler.reset();

    for (int tag : {2, 3, 4}) {
        const auto& failed = only_answer(tag);
        ASSERT_FALSE(failed.ok());
        EXPECT_EQ(failed.error().kind, ErrorKind::link);
        EXPECT_NE(failed.error().message.find("gateway stopping"), std::string::npos);
    }
    EXPECT_TRUE(answers[1].empty());

    master->complete(normal_reply());  // the scheduler is gone; the asker still hears the unit
    EXPECT_EQ(only_answer(1).value(), normal_reply());
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1}));
}

// A reload that keeps the line (LineScheduler::hand_over): the gateway going away hears about
// every request at once, the one on the wire too; nothing is taken until resume(); the reply
// that comes meanwhile reaches no one but still counts, and the next request waits behind it.
TEST_F(LineSchedulerTest, AHandOverAnswersEveryAskerAtOnceAndTheLineCarriesOnAfterResume) {
    submit(1, Priority::poll, 2);  // on the wire
    submit(2, Priority::poll);
    submit(3, Priority::client);
    submit(4, Priority::write);
    scheduler->hand_over();
    for (int tag : {1, 2, 3, 4}) {
        const auto& failed = only_answer(tag);
        ASSERT_FALSE(failed.ok());
        EXPECT_EQ(failed.error().kind, ErrorKind::link);
        EXPECT_NE(failed.error().message.find("gateway reloading"), std::string::npos) << failed.error().message;
        EXPECT_TRUE(abandoned(failed.error())) << "tag " << tag << ": would change the device's status";
    }
    submit(5);  // between the two gateways: refused, never sent
    EXPECT_NE(only_answer(5).error().message.find("gateway reloading"), std::string::npos);

    scheduler->resume();
    submit(6);  // the next gateway's: behind the request still on the wire
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1}));
    master->complete(timed_out());  // request 1's outcome: told to no one, counted for the line
    EXPECT_EQ(answers[1].size(), 1U);
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 6}));
    master->complete(normal_reply());
    EXPECT_EQ(only_answer(6).value(), normal_reply());
    const auto stats = scheduler->statistics();
    EXPECT_EQ(stats.sent, 2U);
    EXPECT_EQ(stats.timeouts, 1U);
    EXPECT_EQ(stats.answered, 1U);
    EXPECT_TRUE(scheduler->hold_poll(2)) << "unit 2's silence did not start its back-off";
}

TEST_F(LineSchedulerTest, DoneMayDestroyTheScheduler) {
    auto first = ask(1);
    first.done = [this](Result<Bytes> result) {
        answers[1].push_back(std::move(result));
        scheduler.reset();  // the owner shuts down on the first answer
    };
    scheduler->submit(std::move(first));
    submit(2);
    master->complete(normal_reply());
    EXPECT_TRUE(only_answer(1).ok());
    EXPECT_EQ(only_answer(2).error().kind, ErrorKind::link);
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1}));
}

TEST_F(LineSchedulerTest, DoneMayDestroyTheSchedulerWhenTheMasterAnswersAtOnce) {
    master->instant = true;
    auto first = ask(1);
    first.done = [this](Result<Bytes> result) {
        answers[1].push_back(std::move(result));
        scheduler.reset();  // must not wait for the forward_async this answer came out of
    };
    scheduler->submit(std::move(first));
    EXPECT_TRUE(only_answer(1).ok());
    EXPECT_EQ(scheduler, nullptr);
}

// ---- the queue's bound (LineSchedulerOptions::max_queued) ---------------------------------

class BoundedLineSchedulerTest : public LineSchedulerTest {
protected:
    BoundedLineSchedulerTest() {
        LineSchedulerOptions options = backoff_options();
        options.max_queued = 3;
        scheduler = std::make_unique<LineScheduler>(master, options, clock);
    }
};

// Past the bound a client's request is refused at once with exception 06h, "server device
// busy" (Modbus application protocol V1.1b3, 7), never queued; what was queued keeps its turn.
TEST_F(BoundedLineSchedulerTest, PastTheBoundARequestIsRefusedBusyAtOnce) {
    submit(1);  // on the wire: not queued
    for (int tag = 2; tag <= 4; ++tag) submit(tag, Priority::client, 1, static_cast<std::uint64_t>(tag));
    submit(5, Priority::write, 1, 5);
    ASSERT_EQ(answers[5].size(), 1U) << "the refusal must come at once, not after the queue";
    const auto& refused = answers[5].front();
    ASSERT_FALSE(refused.ok());
    EXPECT_EQ(refused.error().kind, ErrorKind::exception);
    EXPECT_EQ(refused.error().code, server_device_busy);
    EXPECT_NE(refused.error().message.find("3 requests waiting"), std::string::npos) << refused.error().message;
    // Polls are the gateway's own and are not bounded here.
    submit(6, Priority::poll);
    EXPECT_TRUE(answers[6].empty());
    complete_all();
    // The poll takes the turn after the client's request on the wire: polls and clients alternate.
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 6, 2, 3, 4}));
    const auto stats = scheduler->statistics();
    EXPECT_EQ(stats.refused_busy, 1U);
    EXPECT_EQ(stats.queued, 0U);
}

// A full queue first drops what nobody waits for any more (a closed connection's requests, or
// ones past their deadline), counted as when their turn would have come, and then has room.
TEST_F(BoundedLineSchedulerTest, AFullQueueDropsRequestsNobodyWantsBeforeRefusingOne) {
    submit(1);  // on the wire
    auto connection_open = std::make_shared<std::atomic<bool>>(true);
    for (int tag = 2; tag <= 3; ++tag) {
        auto request = ask(tag, Priority::client, 1, 7);
        request.still_wanted = connection_open;
        scheduler->submit(std::move(request));
    }
    auto late = ask(4, Priority::client, 1, 8);
    late.deadline = clock->now() + 10ms;
    scheduler->submit(std::move(late));
    *connection_open = false;
    clock->sleep_for(10ms);
    submit(5, Priority::client, 1, 9);
    EXPECT_TRUE(answers[5].empty()) << "refused although three queued requests were wanted by nobody";
    for (int tag : {2, 3, 4}) {
        ASSERT_EQ(answers[tag].size(), 1U) << "request " << tag << " was not dropped when room was made";
        EXPECT_FALSE(answers[tag].front().ok());
    }
    complete_all();
    EXPECT_EQ(master->sent_tags(), (std::vector<int>{1, 5}));
    const auto stats = scheduler->statistics();
    EXPECT_EQ(stats.abandoned, 2U);
    EXPECT_EQ(stats.expired, 1U);
    EXPECT_EQ(stats.refused_busy, 0U);
}

// ---------------------------------------------------------------------------------------------
// Sharing the line under load, in virtual time. Every request takes `wire` on the line. Each
// client keeps a request queued at all times (it asks again the moment it is answered). Each
// polled device behaves as the gateway's poller (client/monitor_loop.hpp): from its slot of a
// fixed schedule it sends its poll's requests one after the other, each with the interval as the
// longest it may wait for the line (gateway/poll_groups.cpp), and skips a slot it is still busy
// in.

// Holds the request on the wire until the test completes it, noting when it was sent.
class WireMaster final : public session::Master {
public:
    explicit WireMaster(std::shared_ptr<VirtualClock> clock) : clock_(std::move(clock)) {}

    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override { return forward_only(); }
    void execute_async(std::uint8_t, codec::Request, Completion done) override { done(forward_only()); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return make_error(ErrorKind::link, "not here"); }
    std::string describe() const override { return "wire master"; }

    void forward_async(std::uint8_t, Bytes, ForwardCompletion done) override {
        if (held_) ADD_FAILURE() << "two requests on the wire";
        held_ = std::move(done);
        sent_at_ = clock_->now();
    }

    bool on_wire() const { return static_cast<bool>(held_); }
    Instant sent_at() const { return sent_at_; }
    void complete() {
        auto done = std::move(held_);
        held_ = nullptr;
        done(normal_reply());
    }

private:
    std::shared_ptr<VirtualClock> clock_;
    ForwardCompletion held_;
    Instant sent_at_{};
};

struct PolledDevice {
    std::chrono::milliseconds interval;
    int requests;  // per poll
    // What happened:
    int polls = 0;    // completed
    int missed = 0;   // slots skipped: the poll before was still under way
    int failed = 0;   // requests dropped unsent (their deadline passed)
    Instant::duration longest{};  // from a slot to its poll's last reply
    // The poll under way:
    Instant next_slot{};
    Instant slot{};
    int request = 0;  // 1-based; 0 when idle
};

class LoadedLine : public ::testing::Test {
protected:
    static constexpr auto wire = 20ms;  // e.g. ten registers at 19200 baud with the gaps

    void start(int client_count, std::vector<PolledDevice> polled) {
        devices = std::move(polled);
        for (auto& device : devices) device.next_slot = clock->now();
        for (int client = 0; client < client_count; ++client) ask_as_client(client);
    }

    // Runs the line for `length` of virtual time: each reply `wire` after its request went, each
    // poll on its slot.
    void run_for(Instant::duration length) {
        const Instant end = clock->now() + length;
        for (;;) {
            Instant slot = Instant::max();
            for (const auto& device : devices) slot = std::min(slot, device.next_slot);
            const Instant reply = master->on_wire() ? master->sent_at() + wire : Instant::max();
            const Instant next = std::min(slot, reply);
            if (next >= end) break;
            clock->sleep_until(next);
            if (reply <= slot) {
                master->complete();
            } else {
                start_due_polls();
            }
        }
        clock->sleep_until(end);
    }

    void ask_as_client(int client) {
        LineRequest request;
        request.unit = 1;
        request.pdu = pdu_for(1000 + client);
        request.priority = Priority::client;
        request.client = static_cast<std::uint64_t>(client);
        request.done = [this, client](Result<Bytes> result) {
            if (result.ok()) ++client_answers;
            if (!stopped) ask_as_client(client);
        };
        scheduler->submit(std::move(request));
    }

    void start_due_polls() {
        for (std::size_t i = 0; i < devices.size(); ++i) {
            PolledDevice& device = devices[i];
            if (device.next_slot > clock->now()) continue;
            if (device.request != 0) {
                ++device.missed;
            } else {
                device.slot = device.next_slot;
                device.request = 1;
                send_poll_request(i);
            }
            device.next_slot += device.interval;
        }
    }

    void send_poll_request(std::size_t i) {
        PolledDevice& device = devices[i];
        LineRequest request;
        request.unit = 2;
        request.pdu = pdu_for(100 * static_cast<int>(i + 1) + device.request);
        request.priority = Priority::poll;
        request.deadline = clock->now() + device.interval;
        request.done = [this, i](Result<Bytes> result) { poll_answered(i, result.ok()); };
        scheduler->submit(std::move(request));
    }

    void poll_answered(std::size_t i, bool ok) {
        PolledDevice& device = devices[i];
        if (!ok) {
            ++device.failed;
            device.request = 0;
            return;
        }
        if (device.request < device.requests) {
            ++device.request;
            send_poll_request(i);
            return;
        }
        ++device.polls;
        device.longest = std::max(device.longest, clock->now() - device.slot);
        device.request = 0;
    }

    void TearDown() override {
        stopped = true;
        scheduler.reset();  // fails what is queued; before the master, as an owner must
    }

    std::shared_ptr<VirtualClock> clock = std::make_shared<VirtualClock>();
    std::shared_ptr<WireMaster> master = std::make_shared<WireMaster>(clock);
    std::unique_ptr<LineScheduler> scheduler = std::make_unique<LineScheduler>(master, LineSchedulerOptions{}, clock);
    std::vector<PolledDevice> devices;
    int client_answers = 0;
    bool stopped = false;
};

// The field's case: ten Modbus TCP clients reading back to back used to hold every poll for
// minutes. With polls needing 10 % of the line, every poll of every device is still made on
// time, and the clients get the rest.
TEST_F(LoadedLine, TenClientsKeepingTheLineFullDoNotSlowThePolls) {
    start(10, {{1000ms, 3}, {500ms, 1}});
    run_for(60s);
    const PolledDevice& every_second = devices[0];
    const PolledDevice& twice_a_second = devices[1];
    EXPECT_EQ(every_second.polls, 60) << "slots 0 s to 59 s";
    EXPECT_EQ(twice_a_second.polls, 120);
    for (const auto& device : devices) {
        EXPECT_EQ(device.missed, 0);
        EXPECT_EQ(device.failed, 0);
        // Each request waits for the one on the wire, a client's and the other device's at most.
        EXPECT_LE(device.longest, device.requests * 4 * wire) << device.interval.count() << " ms";
    }
    const auto stats = scheduler->statistics();
    EXPECT_EQ(stats.polls_sent, 60u * 3u + 120u);
    // The line was never idle: the clients had every turn the polls did not need.
    const auto capacity = static_cast<int>(60s / wire);
    EXPECT_GE(stats.sent, static_cast<std::uint64_t>(capacity - 1));
    EXPECT_GE(client_answers, capacity - 300 - 1);
}

// Polls that need more than half the line (here 80 %) cannot have it while clients want it
// too: they get every other turn while they wait, fall behind (the poll group reports the
// skipped slots), and the clients keep at least half the line.
TEST_F(LoadedLine, PollsNeedingMoreThanHalfTheLineFallBehindAndClientsKeepHalf) {
    start(10, {{100ms, 4}});
    run_for(10s);
    const PolledDevice& device = devices[0];
    const auto stats = scheduler->statistics();
    const auto turns = static_cast<double>(stats.sent);
    EXPECT_GE(static_cast<double>(client_answers) / turns, 0.49);
    // Every other turn while a poll waits; between polls (a skipped slot) the clients have all.
    EXPECT_GE(static_cast<double>(stats.polls_sent) / turns, 0.35);
    EXPECT_GT(device.missed, 20) << "the shortfall shows as skipped slots";
    EXPECT_GT(device.polls, 20);
    EXPECT_EQ(device.failed, 0) << "a poll request waits for one client's at most: never past its deadline";
}

// Without clients the polls have the whole line; without polls the clients do.
TEST_F(LoadedLine, WhoeverIsAloneTakesEveryTurn) {
    start(0, {{100ms, 4}});
    run_for(10s);
    EXPECT_EQ(devices[0].polls, 100);
    EXPECT_EQ(devices[0].missed, 0);
    EXPECT_EQ(devices[0].longest, 4 * wire);
}

// Completes each request on its own thread after a short wait, as a serial master does.
class ThreadedMaster final : public session::Master {
public:
    ThreadedMaster() : worker_([this] { run(); }) {}
    ~ThreadedMaster() override {
        {
            std::lock_guard lock(mutex_);
            stopping_ = true;
        }
        ready_.notify_all();
        worker_.join();
    }

    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override { return forward_only(); }
    void execute_async(std::uint8_t, codec::Request, Completion done) override { done(forward_only()); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return make_error(ErrorKind::link, "not here"); }
    std::string describe() const override { return "threaded master"; }

    void forward_async(std::uint8_t, Bytes pdu, ForwardCompletion done) override {
        if (on_wire_.exchange(true)) overlaps_.fetch_add(1);
        std::lock_guard lock(mutex_);
        jobs_.push_back({std::move(pdu), std::move(done)});
        ready_.notify_one();
    }

    int overlaps() const { return overlaps_.load(); }

private:
    struct Job {
        Bytes pdu;
        ForwardCompletion done;
    };

    void run() {
        std::unique_lock lock(mutex_);
        for (;;) {
            ready_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
            if (jobs_.empty()) return;
            auto job = std::move(jobs_.front());
            jobs_.pop_front();
            lock.unlock();
            std::this_thread::sleep_for(20us);  // the line's turnaround
            on_wire_.store(false);
            // Every tenth request gets a garbled reply, so both outcomes are counted.
            if (tag_of(job.pdu) % 10 == 0) {
                job.done(make_error(ErrorKind::malformed, "bad CRC"));
            } else {
                job.done(normal_reply());
            }
            lock.lock();
        }
    }

    std::mutex mutex_;
    std::condition_variable ready_;
    std::deque<Job> jobs_;
    bool stopping_ = false;
    std::atomic<bool> on_wire_{false};
    std::atomic<int> overlaps_{0};
    std::thread worker_;  // last: starts once the rest is ready
};

TEST(LineSchedulerThreads, EveryDoneRunsOnceWithRealThreads) {
    constexpr int submitters = 4;
    constexpr int each = 200;
    constexpr int total = submitters * each;
    auto master = std::make_shared<ThreadedMaster>();
    std::vector<std::atomic<int>> calls(total);
    std::atomic<int> bad{0};
    std::mutex mutex;
    std::condition_variable all_done;
    int finished = 0;
    // Every request queued at once is the point here, not the queue's bound.
    LineSchedulerOptions options;
    options.max_queued = static_cast<std::size_t>(total);
    auto scheduler = std::make_unique<LineScheduler>(master, options);

    std::vector<std::thread> threads;
    for (int thread = 0; thread < submitters; ++thread) {
        threads.emplace_back([&, thread] {
            for (int i = 0; i < each; ++i) {
                const int tag = thread * each + i;
                LineRequest request;
                request.unit = static_cast<std::uint8_t>(1 + tag % 3);
                request.pdu = pdu_for(tag);
                request.priority = static_cast<Priority>(tag % 3);
                request.client = static_cast<std::uint64_t>(thread);
                request.done = [&, tag](Result<Bytes> result) {
                    if (!result.ok()) bad.fetch_add(1);
                    calls[static_cast<std::size_t>(tag)].fetch_add(1);
                    std::lock_guard lock(mutex);
                    ++finished;
                    all_done.notify_all();
                };
                scheduler->submit(std::move(request));
            }
        });
    }
    for (auto& thread : threads) thread.join();
    {
        std::unique_lock lock(mutex);
        ASSERT_TRUE(all_done.wait_for(lock, 60s, [&] { return finished >= total; }))
            << finished << " of " << total << " answered";
    }

    const auto stats = scheduler->statistics();
    scheduler.reset();  // before the master, as an owner must
    for (int tag = 0; tag < total; ++tag) EXPECT_EQ(calls[static_cast<std::size_t>(tag)].load(), 1) << tag;
    EXPECT_EQ(master->overlaps(), 0);
    EXPECT_EQ(stats.sent, static_cast<std::uint64_t>(total));
    EXPECT_EQ(stats.answered + stats.bad_replies, stats.sent);
    EXPECT_EQ(stats.bad_replies, static_cast<std::uint64_t>(total / 10));
    EXPECT_EQ(bad.load(), total / 10);
    EXPECT_EQ(stats.queued, 0U);
}

}  // namespace
}  // namespace loopwire::gateway
