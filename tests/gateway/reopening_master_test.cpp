// A line that comes back by itself (gateway/reopening_master.hpp), in virtual time: a port that
// cannot be opened is tried again 1 s, 2 s, 4 s ... up to every 30 s; a link that fails under a
// request is closed and the line is down, every request failing at once with the reason, until
// the next due request reopens it; each change of state is logged once, not each try.
#include <gtest/gtest.h>
#include <gmock/gmock.h>

#include <atomic>
#include <chrono>
#include <deque>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/never_sent.hpp"
#include "gateway/reopening_master.hpp"
#include "session/line_loop.hpp"
#include "session/slave.hpp"
#include "simulation/register_bank.hpp"
#include "simulation/simulated_lines.hpp"
#include "support/eventually.hpp"
#include "support/thread_names.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using ::testing::Not;

Bytes read_pdu() { return Bytes{0x03, 0x00, 0x00, 0x00, 0x01}; }
Bytes normal_reply() { return Bytes{0x03, 0x02, 0x00, 0x2A}; }

// What one opened link does: answers every request until hung up, then fails as a port whose
// other end went away does. Shared with the test, which outlives the master.
struct LinkScript {
    std::atomic<bool> hung_up{false};
    std::atomic<bool> closed{false};
    std::atomic<unsigned> requests{0};
};

class ScriptedLink final : public session::Master {
public:
    explicit ScriptedLink(std::shared_ptr<LinkScript> script) : script_(std::move(script)) {}
    ~ScriptedLink() override { script_->closed = true; }

    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override {
        return make_error(ErrorKind::usage, "the scripted link only forwards");
    }
    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override { done(execute(unit, request)); }
    Result<Bytes> forward(std::uint8_t, ByteView) override {
        ++script_->requests;
        if (script_->hung_up) {
            return make_error(ErrorKind::link, "serial port /dev/ttyUSB0 hung up: the adapter was unplugged (Input/output error)");
        }
        return normal_reply();
    }
    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override { done(forward(unit, pdu)); }
    std::string describe() const override { return "scripted link"; }

private:
    std::shared_ptr<LinkScript> script_;
};

// Opens links by the script the test queues: a failure (its message) or a link that answers.
// Records the virtual time of each open.
class ScriptedOpener {
public:
    explicit ScriptedOpener(std::shared_ptr<VirtualClock> clock) : clock_(std::move(clock)) {}

    void fail_with(std::string message, ErrorKind kind = ErrorKind::link) {
        std::lock_guard lock(mutex_);
        failures_.push_back(make_error(kind, std::move(message)));
    }
    // From now on every open fails with `message`.
    void always_fail(std::string message) {
        std::lock_guard lock(mutex_);
        always_ = make_error(ErrorKind::link, std::move(message));
    }
    void succeed() {
        std::lock_guard lock(mutex_);
        always_.reset();
        failures_.clear();
    }

    MasterOpener opener() {
        return [this]() -> Result<std::unique_ptr<session::Master>> {
            std::lock_guard lock(mutex_);
            opened_at_.push_back(clock_->now());
            if (!failures_.empty()) {
                auto failure = failures_.front();
                failures_.pop_front();
                return failure;
            }
            if (always_) return *always_;
            links_.push_back(std::make_shared<LinkScript>());
            return std::unique_ptr<session::Master>(std::make_unique<ScriptedLink>(links_.back()));
        };
    }

    // When each open was tried, in seconds after `start`.
    std::vector<double> tries_since(Instant start) const {
        std::lock_guard lock(mutex_);
        std::vector<double> seconds;
        for (const auto at : opened_at_) seconds.push_back(std::chrono::duration<double>(at - start).count());
        return seconds;
    }

    std::shared_ptr<LinkScript> link(std::size_t index) const {
        std::lock_guard lock(mutex_);
        return links_.at(index);
    }

private:
    std::shared_ptr<VirtualClock> clock_;
    mutable std::mutex mutex_;
    std::deque<Error> failures_;
    std::optional<Error> always_;
    std::vector<Instant> opened_at_;
    std::vector<std::shared_ptr<LinkScript>> links_;
};

class ReopeningMasterTest : public ::testing::Test {
protected:
    std::unique_ptr<ReopeningMaster> make_line() {
        return std::make_unique<ReopeningMaster>("furnace", "rtu:/dev/ttyUSB0?baud=19200", opener.opener(), ReopenSchedule{},
                                                 clock, [this](const std::string& line) {
                                                     std::lock_guard lock(log_mutex);
                                                     log.push_back(line);
                                                 });
    }

    std::vector<std::string> logged() {
        std::lock_guard lock(log_mutex);
        return log;
    }

    std::shared_ptr<VirtualClock> clock = std::make_shared<VirtualClock>();
    ScriptedOpener opener{clock};
    std::mutex log_mutex;
    std::vector<std::string> log;
};

TEST_F(ReopeningMasterTest, APortThatCannotBeOpenedIsTriedAfterOneTwoFourSecondsUpToEveryThirty) {
    opener.always_fail("no such port /dev/ttyUSB0 — check the path; is the adapter plugged in?");
    const Instant start = clock->now();
    auto line = make_line();
    ASSERT_TRUE(line->start().ok()) << "a missing port is a line that is down, not an error";
    EXPECT_FALSE(line->health().up);

    // Requests every 100 ms of virtual time for two minutes: each that finds the wait over is
    // the one that tries to open the port; every one fails at once, saying why and when next.
    std::vector<std::string> errors;
    for (auto elapsed = 0ms; elapsed <= 125s; elapsed += 100ms) {
        clock->sleep_until(start + elapsed);
        auto reply = line->forward(3, read_pdu());
        ASSERT_FALSE(reply.ok());
        EXPECT_EQ(reply.error().kind, ErrorKind::link);
        errors.push_back(reply.error().message);
    }
    EXPECT_EQ(opener.tries_since(start), (std::vector<double>{0, 1, 3, 7, 15, 31, 61, 91, 121}));
    EXPECT_EQ(errors.front(),
              "line furnace (rtu:/dev/ttyUSB0?baud=19200) is down: no such port /dev/ttyUSB0 — check the path; is the "
              "adapter plugged in?; retrying in 1 s");
    EXPECT_THAT(errors.at(40), HasSubstr("; retrying in 3 s"));  // at 4.0 s: tried at 3 s, next at 7 s

    const auto health = line->health();
    EXPECT_FALSE(health.up);
    EXPECT_EQ(health.down_periods, 1u);
    EXPECT_EQ(health.reopen_attempts, 8u);
    EXPECT_EQ(health.reopened, 0u);
    EXPECT_EQ(health.retry_in, 26000ms);  // at 125 s; next try at 151 s
    EXPECT_EQ(health.down_time, 125s);
    // Nine tries, one line in the log: the reason never changed.
    ASSERT_EQ(logged().size(), 1u);
    EXPECT_THAT(logged()[0], HasSubstr("line furnace (rtu:/dev/ttyUSB0?baud=19200) is down: no such port /dev/ttyUSB0"));
    EXPECT_THAT(logged()[0], HasSubstr("reopening it in 1 s, then with back-off up to every 30 s"));
}

TEST_F(ReopeningMasterTest, ALinkThatFailsUnderARequestIsClosedAndReopenedByTheFirstRequestDueAfterIt) {
    const Instant start = clock->now();
    auto line = make_line();
    ASSERT_TRUE(line->start().ok());
    ASSERT_TRUE(line->health().up);
    EXPECT_EQ(line->forward(3, read_pdu()).value(), normal_reply());

    // The adapter is pulled out: the request that finds it fails, and the line is down.
    const auto first = opener.link(0);
    first->hung_up = true;
    auto failed = line->forward(3, read_pdu());
    ASSERT_FALSE(failed.ok());
    EXPECT_EQ(failed.error().kind, ErrorKind::link);
    EXPECT_THAT(failed.error().message, HasSubstr("line furnace (rtu:/dev/ttyUSB0?baud=19200) is down: serial port "
                                                  "/dev/ttyUSB0 hung up"));
    EXPECT_THAT(failed.error().message, HasSubstr("retrying in 1 s"));
    EXPECT_TRUE(first->closed) << "the failed link is still open";
    EXPECT_FALSE(line->health().up);

    // Until the wait is over, requests fail at once: the port is not touched.
    clock->advance(999ms);
    const auto refused = line->forward(3, read_pdu());
    ASSERT_FALSE(refused.ok());
    EXPECT_THAT(refused.error().message, HasSubstr("retrying in 1 s"));
    EXPECT_EQ(opener.tries_since(start).size(), 1u);

    // The first request after it opens the port again and goes through.
    clock->advance(1ms);
    EXPECT_EQ(line->forward(3, read_pdu()).value(), normal_reply());
    EXPECT_EQ(opener.tries_since(start), (std::vector<double>{0, 1}));
    EXPECT_EQ(opener.link(1)->requests, 1u);

    const auto health = line->health();
    EXPECT_TRUE(health.up);
    EXPECT_TRUE(health.reason.empty());
    EXPECT_EQ(health.down_periods, 1u);
    EXPECT_EQ(health.reopen_attempts, 1u);
    EXPECT_EQ(health.reopened, 1u);
    EXPECT_EQ(health.down_time, 1s);
    const auto lines = logged();
    ASSERT_EQ(lines.size(), 2u);
    EXPECT_THAT(lines[0], HasSubstr("is down: serial port /dev/ttyUSB0 hung up"));
    EXPECT_EQ(lines[1], "notice: line furnace (rtu:/dev/ttyUSB0?baud=19200) is up again after 1.0 s down (1 reopen attempt)");
}

TEST_F(ReopeningMasterTest, TheWaitStartsOverAtOneSecondEachTimeTheLineGoesDown) {
    const Instant start = clock->now();
    auto line = make_line();
    ASSERT_TRUE(line->start().ok());
    opener.link(0)->hung_up = true;
    ASSERT_FALSE(line->forward(3, read_pdu()).ok());  // down at 0 s
    opener.fail_with("no such port /dev/ttyUSB0");
    opener.fail_with("no such port /dev/ttyUSB0");
    clock->advance(1s);
    ASSERT_FALSE(line->forward(3, read_pdu()).ok());  // tried at 1 s
    clock->advance(2s);
    ASSERT_FALSE(line->forward(3, read_pdu()).ok());  // tried at 3 s
    clock->advance(4s);
    ASSERT_TRUE(line->forward(3, read_pdu()).ok());  // up at 7 s
    opener.link(1)->hung_up = true;
    ASSERT_FALSE(line->forward(3, read_pdu()).ok());  // down again at 7 s
    clock->advance(1s);
    EXPECT_TRUE(line->forward(3, read_pdu()).ok()) << "the second period did not start at 1 s";
    EXPECT_EQ(opener.tries_since(start), (std::vector<double>{0, 1, 3, 7, 8}));
    const auto health = line->health();
    EXPECT_EQ(health.down_periods, 2u);
    EXPECT_EQ(health.reopen_attempts, 4u);
    EXPECT_EQ(health.reopened, 2u);
    EXPECT_EQ(health.down_time, 8s);
    // Down, still down for another reason, up, down, up: one line each.
    const auto lines = logged();
    ASSERT_EQ(lines.size(), 5u) << ::testing::PrintToString(lines);
    EXPECT_THAT(lines[1], HasSubstr("is still down, now because: no such port /dev/ttyUSB0"));
    EXPECT_THAT(lines[2], HasSubstr("is up again after 7.0 s down (3 reopen attempts)"));
}

TEST_F(ReopeningMasterTest, WhileDownAnAsynchronousRequestIsAnsweredBeforeItReturns) {
    opener.always_fail("no such port /dev/ttyUSB0");
    auto line = make_line();
    ASSERT_TRUE(line->start().ok());
    clock->advance(500ms);
    std::optional<Result<Bytes>> answered;
    line->forward_async(3, read_pdu(), [&](Result<Bytes> result) { answered.emplace(std::move(result)); });
    ASSERT_TRUE(answered.has_value()) << "a request for a line that is down waited for the line's thread";
    ASSERT_FALSE(answered->ok());
    EXPECT_THAT(answered->error().message, HasSubstr("is down: no such port /dev/ttyUSB0; retrying in 1 s"));
}

TEST_F(ReopeningMasterTest, AnAsynchronousRequestDueForAReopenOpensTheLineOnItsThread) {
    opener.fail_with("no such port /dev/ttyUSB0");
    auto line = make_line();
    ASSERT_TRUE(line->start().ok());
    clock->advance(1s);
    std::promise<Result<Bytes>> answered;
    auto reply = answered.get_future();
    line->forward_async(3, read_pdu(), [&](Result<Bytes> result) { answered.set_value(std::move(result)); });
    ASSERT_EQ(reply.wait_for(30s), std::future_status::ready);
    EXPECT_EQ(reply.get().value(), normal_reply());
    EXPECT_TRUE(line->health().up);
}

TEST_F(ReopeningMasterTest, AConfigurationNoPortCanTakeIsAnErrorAtStart) {
    opener.fail_with("serial port /dev/ttyUSB0: baud 12345 is not supported", ErrorKind::usage);
    auto line = make_line();
    const auto started = line->start();
    ASSERT_FALSE(started.ok());
    EXPECT_EQ(started.error().kind, ErrorKind::usage);
    EXPECT_EQ(started.error().message,
              "line furnace (rtu:/dev/ttyUSB0?baud=19200): serial port /dev/ttyUSB0: baud 12345 is not supported");
}

// A Modbus TCP link that holds every request until the test answers it, several at once, as a
// reader thread matching replies by transaction id would; destroyed, it fails what it still holds
// (as the TCP master does) and notes the thread it was destroyed on.
struct HeldLinkScript {
    std::mutex mutex;
    std::deque<session::Master::ForwardCompletion> held;
    std::atomic<bool> closed{false};
    std::thread::id closed_on;

    std::size_t waiting() {
        std::lock_guard lock(mutex);
        return held.size();
    }
    session::Master::ForwardCompletion oldest() {
        std::lock_guard lock(mutex);
        auto done = std::move(held.front());
        held.pop_front();
        return done;
    }
};

class HeldLink final : public session::Master {
public:
    explicit HeldLink(std::shared_ptr<HeldLinkScript> script) : script_(std::move(script)) {}
    ~HeldLink() override {
        std::deque<ForwardCompletion> left;
        {
            std::lock_guard lock(script_->mutex);
            left.swap(script_->held);
            script_->closed_on = std::this_thread::get_id();
        }
        for (auto& done : left) done(make_error(ErrorKind::link, "master closed"));
        script_->closed = true;
    }

    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override {
        return make_error(ErrorKind::usage, "the held link only forwards");
    }
    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override { done(execute(unit, request)); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return normal_reply(); }
    void forward_async(std::uint8_t, Bytes, ForwardCompletion done) override {
        std::lock_guard lock(script_->mutex);
        script_->held.push_back(std::move(done));
    }
    std::string describe() const override { return "held link"; }
    // As the TCP master's: what it holds fails now, on the caller's thread, marked abandoned.
    void close() override {
        std::deque<ForwardCompletion> left;
        {
            std::lock_guard lock(script_->mutex);
            left.swap(script_->held);
        }
        for (auto& done : left) done(make_error(ErrorKind::link, "held link: closed, not waited for", abandoned_code));
    }

private:
    std::shared_ptr<HeldLinkScript> script_;
};

// LinkConcurrency::several: requests reach the open link together instead of one at a time by
// the worker; a link failure one of them meets on the link's own thread takes the line down, and
// the link is closed on another thread (never its own, which would wait for itself).
TEST(ConcurrentReopeningMaster, CarriesSeveralAtOnceAndClosesALinkThatFailedUnderThemOnItsWorker) {
    auto clock = std::make_shared<VirtualClock>();
    std::vector<std::shared_ptr<HeldLinkScript>> links;
    std::mutex links_mutex;
    MasterOpener open = [&]() -> Result<std::unique_ptr<session::Master>> {
        std::lock_guard lock(links_mutex);
        links.push_back(std::make_shared<HeldLinkScript>());
        return std::unique_ptr<session::Master>(std::make_unique<HeldLink>(links.back()));
    };
    // Before the line: its destructor fails what the link still holds, into these.
    std::mutex answers_mutex;
    std::vector<Result<Bytes>> answers;
    auto record = [&](Result<Bytes> result) {
        std::lock_guard lock(answers_mutex);
        answers.push_back(std::move(result));
    };
    ReopeningMaster line("plc", "tcp://192.0.2.7:502", open, ReopenSchedule{}, clock, {}, LinkConcurrency::several);
    ASSERT_TRUE(line.start().ok());
    const auto first = links.at(0);

    for (int request = 0; request < 3; ++request) line.forward_async(1, read_pdu(), record);
    EXPECT_EQ(first->waiting(), 3U) << "the requests were not all handed to the link at once";

    first->oldest()(normal_reply());
    // The connection drops: the link's reader thread fails the next request.
    std::thread reader([&] { first->oldest()(make_error(ErrorKind::link, "connection to 192.0.2.7:502 lost: reset")); });
    reader.join();
    ASSERT_TRUE(loopwire::testing::eventually([&] { return first->closed.load(); })) << "never: the failed link was closed";
    EXPECT_NE(first->closed_on, std::thread::id()) << "closed without a thread";
    EXPECT_NE(first->closed_on, std::this_thread::get_id());
    {
        std::lock_guard lock(answers_mutex);
        ASSERT_EQ(answers.size(), 3U) << "closing the link did not fail the request it still held";
        EXPECT_TRUE(answers[0].ok());
        // The reader thread hands its failure on while the worker closes the link under the
        // third request: either may be recorded first, so they are told apart by their text.
        ASSERT_FALSE(answers[1].ok());
        ASSERT_FALSE(answers[2].ok());
        const bool second_met_the_loss = answers[1].error().message.find("lost") != std::string::npos;
        const auto& met_the_loss = second_met_the_loss ? answers[1] : answers[2];
        const auto& was_held = second_met_the_loss ? answers[2] : answers[1];
        EXPECT_THAT(met_the_loss.error().message, HasSubstr("connection to 192.0.2.7:502 lost"));
        EXPECT_EQ(was_held.error().kind, ErrorKind::link);
        EXPECT_THAT(was_held.error().message, Not(HasSubstr("lost")));
    }
    EXPECT_FALSE(line.health().up);
    EXPECT_THAT(line.health().reason, HasSubstr("connection to 192.0.2.7:502 lost"));

    // Down: refused at once. A second later the next request reopens the line, and requests
    // after it go straight to the new link again.
    std::optional<Result<Bytes>> refused;
    line.forward_async(1, read_pdu(), [&](Result<Bytes> result) { refused.emplace(std::move(result)); });
    ASSERT_TRUE(refused.has_value());
    EXPECT_THAT(refused->error().message, HasSubstr("line plc (tcp://192.0.2.7:502) is down"));
    clock->advance(1s);
    std::promise<Result<Bytes>> reopened;
    line.forward_async(1, read_pdu(), [&](Result<Bytes> result) { reopened.set_value(std::move(result)); });
    auto reply = reopened.get_future();
    ASSERT_EQ(reply.wait_for(30s), std::future_status::ready);
    EXPECT_EQ(reply.get().value(), normal_reply());
    EXPECT_TRUE(line.health().up);
    std::shared_ptr<HeldLinkScript> second;
    {
        std::lock_guard lock(links_mutex);
        ASSERT_EQ(links.size(), 2U);
        second = links.at(1);
    }
    line.forward_async(1, read_pdu(), record);
    line.forward_async(1, read_pdu(), record);
    EXPECT_EQ(second->waiting(), 2U);
}

// A gateway that stops closes its lines: on a Modbus TCP line the link fails what it awaits right
// there, on the closing thread, and a completion that hands the line its next request (as the
// line's scheduler does) is refused at once, marked abandoned, without deadlocking on the line;
// the line is not taken for down.
TEST(ConcurrentReopeningMaster, CloseEndsWhatTheLinkAwaitsAndRefusesWhatComesNextWithoutTakingTheLineDown) {
    auto clock = std::make_shared<VirtualClock>();
    auto script = std::make_shared<HeldLinkScript>();
    MasterOpener open = [script]() -> Result<std::unique_ptr<session::Master>> {
        return std::unique_ptr<session::Master>(std::make_unique<HeldLink>(script));
    };
    ReopeningMaster line("plc", "tcp://192.0.2.7:502", open, ReopenSchedule{}, clock, {}, LinkConcurrency::several);
    ASSERT_TRUE(line.start().ok());
    std::promise<Result<Bytes>> next;
    std::optional<Result<Bytes>> awaited;
    line.forward_async(1, read_pdu(), [&](Result<Bytes> result) {
        awaited.emplace(std::move(result));
        line.forward_async(1, read_pdu(), [&next](Result<Bytes> refused) { next.set_value(std::move(refused)); });
    });
    ASSERT_EQ(script->waiting(), 1U);

    auto closed = std::async(std::launch::async, [&line] { line.close(); });
    if (closed.wait_for(30s) != std::future_status::ready) {
        ADD_FAILURE() << "close() did not return: the completion it ran could not reach the line";
        std::abort();  // the closing thread still refers to the line
    }
    ASSERT_TRUE(awaited.has_value());
    ASSERT_FALSE(awaited->ok());
    EXPECT_TRUE(abandoned(awaited->error())) << awaited->error().message;
    auto refused = next.get_future();
    ASSERT_EQ(refused.wait_for(30s), std::future_status::ready);
    const auto after = refused.get();
    ASSERT_FALSE(after.ok());
    EXPECT_TRUE(abandoned(after.error())) << after.error().message;
    EXPECT_THAT(after.error().message, HasSubstr("line plc (tcp://192.0.2.7:502) is closing"));
    EXPECT_EQ(script->waiting(), 0U) << "a request reached the link after close()";
    EXPECT_TRUE(line.health().up);
    EXPECT_EQ(line.health().down_periods, 0U);
}

// A bus port that fails as an unplugged adapter does while the test says so.
class BreakableStream final : public transport::ByteStream {
public:
    BreakableStream(std::unique_ptr<transport::ByteStream> port, std::shared_ptr<std::atomic<bool>> broken)
        : port_(std::move(port)), broken_(std::move(broken)) {}

    Result<void> write(ByteView bytes) override {
        if (*broken_) return unplugged();
        return port_->write(bytes);
    }
    Result<Instant> write_without_waiting(ByteView bytes) override {
        if (*broken_) return unplugged();
        return port_->write_without_waiting(bytes);
    }
    Result<std::size_t> read_some(std::span<std::uint8_t> buffer, std::chrono::milliseconds timeout) override {
        return port_->read_some(buffer, timeout);
    }
    void discard_input() override { port_->discard_input(); }
    int poll_handle() const override { return port_->poll_handle(); }
    std::string describe() const override { return port_->describe(); }

private:
    static Error unplugged() { return make_error(ErrorKind::link, "serial port /dev/ttyUSB3 hung up: the adapter was unplugged"); }

    std::unique_ptr<transport::ByteStream> port_;
    std::shared_ptr<std::atomic<bool>> broken_;
};

// LinkConcurrency::on_loop: a serial line carried by the lines' loop. While it is up no thread
// is the line's own; a link failure takes it down, the next request due reopens it on a worker
// thread, and that worker ends once it has nothing left to do.
TEST(ReopeningMasterOnALoop, AnUpLineHasNoThreadOfItsOwnAndItsWorkerEndsOnceTheLineIsBack) {
    const auto link = *transport::parse_link_url("rtu:virtual?baud=115200");
    auto bus = transport::VirtualBus::create(115200, link.serial.bits_per_character());
    auto bank = std::make_shared<session::RegisterBank>();
    bank->set(codec::Table::holding_registers, 0, 42);
    auto loop = std::make_shared<session::LineLoop>();
    simulation::SimulatedLines devices(loop);
    ASSERT_TRUE(devices.add(bus->attach("devices", transport::VirtualBus::Writes::return_at_once),
                            std::make_unique<session::Slave>(link, session::UnitMap{{1, bank}})));
    auto broken = std::make_shared<std::atomic<bool>>(false);
    std::atomic<int> opened{0};
    MasterOpener open = [&]() -> Result<std::unique_ptr<session::Master>> {
        ++opened;
        session::MasterOptions options;
        options.timeout = 2s;
        options.retries = 2;
        options.loop = loop;
        return session::make_serial_master(std::make_unique<BreakableStream>(bus->attach("gateway"), broken), link, options);
    };
    auto clock = std::make_shared<VirtualClock>();
    ReopeningMaster line("kiln", link.to_string(), open, ReopenSchedule{}, clock, {}, LinkConcurrency::on_loop, loop);
    ASSERT_TRUE(line.start().ok());
    const auto ask = [&line] {
        std::promise<Result<Bytes>> answered;
        line.forward_async(1, read_pdu(), [&answered](Result<Bytes> result) { answered.set_value(std::move(result)); });
        auto future = answered.get_future();
        if (future.wait_for(30s) != std::future_status::ready) return Result<Bytes>(make_error(ErrorKind::timeout, "no answer in 30 s"));
        return future.get();
    };
    for (int i = 0; i < 5; ++i) EXPECT_EQ(ask().value(), normal_reply());
    EXPECT_EQ(testing::threads_named_like("lw-line "), 0U);
    EXPECT_EQ(testing::thread_names().count("lw-serial"), 0U);

    *broken = true;
    auto failed = ask();
    ASSERT_FALSE(failed);
    EXPECT_THAT(failed.error().message, HasSubstr("unplugged"));
    ASSERT_TRUE(loopwire::testing::eventually([&] { return !line.health().up; })) << "never: the line went down";

    *broken = false;
    clock->advance(1s);
    EXPECT_EQ(ask().value(), normal_reply());
    EXPECT_TRUE(line.health().up);
    EXPECT_EQ(opened.load(), 2);
    EXPECT_TRUE(loopwire::testing::eventually([] { return testing::threads_named_like("lw-line ") == 0; })) << "never: the worker ended once idle";
    EXPECT_EQ(ask().value(), normal_reply());
}

// A link on the loop that fails every request as a pulled adapter does, and whose closing takes
// as long as the test says (a loaded machine's worker).
class SlowToCloseLink final : public session::Master {
public:
    SlowToCloseLink(std::shared_ptr<session::LineLoop> loop, std::shared_future<void> closed_when, std::promise<void>& closing)
        : loop_(std::move(loop)), closed_when_(std::move(closed_when)), closing_(closing) {}
    ~SlowToCloseLink() override {
        closing_.set_value();
        closed_when_.wait();
    }
    Result<codec::Reply> execute(std::uint8_t, const codec::Request&) override { return unplugged(); }
    void execute_async(std::uint8_t, codec::Request, Completion done) override {
        loop_->post([done = std::move(done)] { done(unplugged()); });
    }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return unplugged(); }
    void forward_async(std::uint8_t, Bytes, ForwardCompletion done) override {
        loop_->post([done = std::move(done)] { done(unplugged()); });
    }
    std::string describe() const override { return "slow to close"; }

private:
    static Error unplugged() { return make_error(ErrorKind::link, "serial port /dev/ttyUSB3 hung up: the adapter was unplugged"); }

    std::shared_ptr<session::LineLoop> loop_;
    std::shared_future<void> closed_when_;
    std::promise<void>& closing_;
};

// In virtual time the line's time stands still while its worker closes a master a request found
// failed: otherwise the plant clock runs on to the next deadline (here a timer 10 minutes on)
// with the line down and refusing, however soon the adapter is back (the soak's line came back
// 197 s of plant time after its outage when a loaded machine's worker was slow to close).
TEST(ReopeningMasterOnALoop, ClosingAFailedMasterHoldsTheLoopsVirtualTime) {
    auto clock = std::make_shared<VirtualClock>();
    auto loop = std::make_shared<session::LineLoop>(clock);
    std::promise<void> release;
    std::promise<void> closing;
    std::shared_future<void> closed_when = release.get_future().share();
    MasterOpener open = [&]() -> Result<std::unique_ptr<session::Master>> {
        return std::unique_ptr<session::Master>(std::make_unique<SlowToCloseLink>(loop, closed_when, closing));
    };
    ReopeningMaster line("kiln", "rtu:/dev/ttyUSB3?baud=19200", open, ReopenSchedule{}, clock, {}, LinkConcurrency::on_loop, loop);
    ASSERT_TRUE(line.start().ok());
    // Lets the worker go at the end whatever failed (the line joins it as it goes).
    struct ReleaseAtEnd {
        std::promise<void>& release;
        bool released = false;
        void now() {
            if (!std::exchange(released, true)) release.set_value();
        }
        ~ReleaseAtEnd() { now(); }
    } release_at_end{release};
    const Instant start = clock->now();
    std::promise<Instant> timer_fired;
    std::promise<Result<Bytes>> failed;
    loop->post([&] {
        loop->wait(-1, start + 10min, [&] { timer_fired.set_value(clock->now()); });
        line.forward_async(1, read_pdu(), [&](Result<Bytes> result) { failed.set_value(std::move(result)); });
    });
    auto failure = failed.get_future();
    ASSERT_EQ(failure.wait_for(30s), std::future_status::ready);
    EXPECT_THAT(failure.get().error().message, HasSubstr("unplugged"));
    ASSERT_EQ(closing.get_future().wait_for(30s), std::future_status::ready) << "the failed master was never closed";

    // The worker is inside the master's destructor: given time, a loop whose time is not held
    // would jump to the timer.
    auto fired = timer_fired.get_future();
    EXPECT_EQ(fired.wait_for(200ms), std::future_status::timeout) << "the plant clock ran on while the worker closed the line";
    EXPECT_LT(clock->now(), start + 1s);

    release_at_end.now();
    ASSERT_EQ(fired.wait_for(30s), std::future_status::ready) << "the time was never let go";
    EXPECT_EQ(fired.get(), start + 10min);
    EXPECT_FALSE(line.health().up);
}

// close(), as a stopping gateway calls it: a read waiting for a unit that never answers (the
// timeout a minute) ends at once, and so does every request after it, each with a link error
// marked abandoned (common/never_sent.hpp), so that a poll's outcome tells nothing of its device;
// and the line is not taken for down (no outage logged, no reopening).
TEST(ReopeningMasterOnALoop, CloseEndsTheReadUnderWayAndTheLineIsNotDown) {
    const auto link = *transport::parse_link_url("rtu:virtual?baud=115200");
    auto bus = transport::VirtualBus::create(115200, link.serial.bits_per_character());
    auto bank = std::make_shared<session::RegisterBank>();
    auto loop = std::make_shared<session::LineLoop>();
    simulation::SimulatedLines devices(loop);
    ASSERT_TRUE(devices.add(bus->attach("devices", transport::VirtualBus::Writes::return_at_once),
                            std::make_unique<session::Slave>(link, session::UnitMap{{1, bank}})));
    MasterOpener open = [&]() -> Result<std::unique_ptr<session::Master>> {
        session::MasterOptions options;
        options.timeout = 60s;
        options.loop = loop;
        return session::make_serial_master(bus->attach("gateway"), link, options);
    };
    std::vector<std::string> logged;
    std::mutex log_mutex;
    LinkLog log = [&](const std::string& line) {
        std::lock_guard lock(log_mutex);
        logged.push_back(line);
    };
    ReopeningMaster line("kiln", link.to_string(), open, ReopenSchedule{}, steady_clock(), log, LinkConcurrency::on_loop, loop);
    ASSERT_TRUE(line.start().ok());
    std::promise<Result<Bytes>> answered;
    line.forward_async(7, read_pdu(), [&answered](Result<Bytes> result) { answered.set_value(std::move(result)); });  // nobody is unit 7
    line.close();
    auto future = answered.get_future();
    ASSERT_EQ(future.wait_for(30s), std::future_status::ready) << "the read waited on after close()";
    const auto ended = future.get();
    ASSERT_FALSE(ended);
    EXPECT_TRUE(abandoned(ended.error())) << ended.error().message;

    std::promise<Result<Bytes>> refused;
    line.forward_async(1, read_pdu(), [&refused](Result<Bytes> result) { refused.set_value(std::move(result)); });
    const auto after = refused.get_future().get();
    ASSERT_FALSE(after);
    EXPECT_TRUE(abandoned(after.error())) << after.error().message;
    EXPECT_THAT(after.error().message, HasSubstr("is closing"));

    const auto health = line.health();
    EXPECT_TRUE(health.up);
    EXPECT_EQ(health.down_periods, 0U);
    std::lock_guard lock(log_mutex);
    EXPECT_TRUE(logged.empty()) << logged.front();
}

}  // namespace
}  // namespace loopwire::gateway
