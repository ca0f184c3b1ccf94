// What the polls run on (gateway/event_loop.hpp), the same for both loops: the gateway's Engine
// (Asio, steady clock) and LineLoopEvents (a session::LineLoop, here on a virtual clock): timers
// run in the order of their times, a cancelled one or one set again does not run, and on the
// virtual clock ten minutes of timers pass at once, with the wall time stamped as far on.
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <memory>
#include <string>
#include <vector>

#include "gateway/engine.hpp"
#include "gateway/event_loop.hpp"
#include "session/line_loop.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;

// Runs `work` on the loop and waits for what it hands back through `done`, at most 30 s.
template <typename Work>
std::vector<std::string> on_loop(EventLoop& loop, Work work) {
    auto finished = std::make_shared<std::promise<std::vector<std::string>>>();
    auto result = finished->get_future();
    loop.post([&loop, work, finished] { work(loop, finished); });
    if (result.wait_for(30s) != std::future_status::ready) {
        ADD_FAILURE() << "the loop's timers did not run in 30 s";
        return {};
    }
    return result.get();
}

using Finished = std::shared_ptr<std::promise<std::vector<std::string>>>;

// Three timers set out of order, one cancelled: the other two run in the order of their times.
std::vector<std::string> ordered_and_cancelled(EventLoop& loop) {
    return on_loop(loop, [](EventLoop& events, const Finished& finished) {
        auto ran = std::make_shared<std::vector<std::string>>();
        const Instant now = events.clock()->now();
        events.at(now + 30ms, [ran, finished] {
            ran->push_back("30 ms");
            finished->set_value(*ran);
        });
        events.at(now + 10ms, [ran] { ran->push_back("10 ms"); });
        const auto cancelled = events.at(now + 20ms, [ran] { ran->push_back("20 ms, cancelled"); });
        events.cancel(cancelled);
    });
}

// A LoopTimer set again replaces what it was set to; one destroyed never runs.
std::vector<std::string> set_again_and_destroyed(EventLoop& loop) {
    return on_loop(loop, [](EventLoop& events, const Finished& finished) {
        auto ran = std::make_shared<std::vector<std::string>>();
        auto timer = std::make_shared<LoopTimer>(events);
        const Instant now = events.clock()->now();
        timer->set(now + 10ms, [ran] { ran->push_back("first setting"); });
        timer->set(now + 20ms, [ran] { ran->push_back("second setting"); });
        auto destroyed = std::make_unique<LoopTimer>(events);
        destroyed->set(now + 5ms, [ran] { ran->push_back("destroyed timer"); });
        destroyed.reset();
        events.at(now + 40ms, [ran, timer, finished] { finished->set_value(*ran); });
    });
}

TEST(EngineTimers, RunInTheOrderOfTheirTimesAndACancelledOneNeverRuns) {
    Engine engine;
    EXPECT_EQ(ordered_and_cancelled(engine), (std::vector<std::string>{"10 ms", "30 ms"}));
    EXPECT_EQ(set_again_and_destroyed(engine), std::vector<std::string>{"second setting"});
}

TEST(LineLoopEventsTimers, RunInTheOrderOfTheirTimesAndACancelledOneNeverRuns) {
    auto clock = std::make_shared<VirtualClock>();
    LineLoopEvents events(std::make_shared<session::LineLoop>(clock));
    EXPECT_EQ(ordered_and_cancelled(events), (std::vector<std::string>{"10 ms", "30 ms"}));
    EXPECT_EQ(set_again_and_destroyed(events), std::vector<std::string>{"second setting"});
}

TEST(LineLoopEventsTimers, TenMinutesOfVirtualTimePassAtOnceAndTheWallTimeFollows) {
    auto clock = std::make_shared<VirtualClock>();
    LineLoopEvents events(std::make_shared<session::LineLoop>(clock));
    const auto wall_before = events.wall_now();
    const Instant before = clock->now();
    const auto wall_start = std::chrono::steady_clock::now();
    const auto seen = on_loop(events, [before](EventLoop& loop, const Finished& finished) {
        loop.at(before + 10min, [&loop, finished] {
            finished->set_value({std::to_string(std::chrono::duration_cast<std::chrono::seconds>(loop.clock()->now().time_since_epoch()).count())});
        });
    });
    ASSERT_EQ(seen.size(), 1U);
    EXPECT_EQ(seen[0], std::to_string(std::chrono::duration_cast<std::chrono::seconds>((before + 10min).time_since_epoch()).count()));
    // Not a wall-clock bound on the test: only that the loop did not sleep through the 10 minutes.
    EXPECT_LT(std::chrono::steady_clock::now() - wall_start, 5min);
    EXPECT_EQ(std::chrono::duration_cast<std::chrono::seconds>(events.wall_now() - wall_before), std::chrono::seconds(600));
}

}  // namespace
}  // namespace loopwire::gateway
