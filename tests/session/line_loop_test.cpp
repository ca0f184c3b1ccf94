// The lines' shared loop (session/line_loop.hpp): posted jobs in order on its own thread, waits
// that wake on a readable descriptor or a deadline, whichever comes first, and cancelled waits
// that never wake.
#include <gtest/gtest.h>

#include <unistd.h>

#include <array>
#include <future>
#include <vector>

#include "session/line_loop.hpp"
#include "support/thread_names.hpp"

namespace loopwire::session {
namespace {

using namespace std::chrono_literals;

// Runs `job` on the loop and waits for it.
template <typename Job>
void on_loop(LineLoop& loop, Job job) {
    std::promise<void> ran;
    loop.post([&] {
        job();
        ran.set_value();
    });
    ASSERT_EQ(ran.get_future().wait_for(30s), std::future_status::ready) << "the loop did not run a posted job in 30 s";
}

struct Pipe {
    Pipe() { EXPECT_EQ(::pipe(ends.data()), 0); }
    ~Pipe() {
        ::close(ends[0]);
        ::close(ends[1]);
    }
    std::array<int, 2> ends{};
};

TEST(LineLoop, RunsPostedJobsInOrderOnItsOwnNamedThread) {
    LineLoop loop;
    std::vector<int> order;
    bool on_its_thread = true;
    for (int i = 0; i < 100; ++i) {
        loop.post([&, i] {
            order.push_back(i);
            on_its_thread = on_its_thread && loop.on_loop_thread();
        });
    }
    on_loop(loop, [] {});
    ASSERT_EQ(order.size(), 100U);
    for (int i = 0; i < 100; ++i) EXPECT_EQ(order[static_cast<std::size_t>(i)], i);
    EXPECT_TRUE(on_its_thread);
    EXPECT_FALSE(loop.on_loop_thread());
    EXPECT_EQ(testing::thread_names().count("lw-lines"), 1U);
}

// Bytes written to a pipe wake its wait long before the wait's deadline (an hour away).
TEST(LineLoop, AWaitWakesWhenItsDescriptorBecomesReadable) {
    LineLoop loop;
    Pipe pipe;
    std::promise<void> woken;
    on_loop(loop, [&] { loop.wait(pipe.ends[0], std::chrono::steady_clock::now() + 1h, [&] { woken.set_value(); }); });
    auto wake = woken.get_future();
    EXPECT_EQ(wake.wait_for(50ms), std::future_status::timeout) << "woke with nothing to read";
    ASSERT_EQ(::write(pipe.ends[1], "x", 1), 1);
    EXPECT_EQ(wake.wait_for(30s), std::future_status::ready);
}

// Two deadline waits wake in the order of their deadlines, not of their making, and neither
// before its deadline.
TEST(LineLoop, DeadlinesWakeInTheirOrderAndNotBefore) {
    LineLoop loop;
    std::mutex mutex;
    std::vector<std::pair<int, Instant>> woken;
    std::promise<void> both;
    Instant first_due{};
    Instant second_due{};
    on_loop(loop, [&] {
        const auto now = std::chrono::steady_clock::now();
        second_due = now + 80ms;
        first_due = now + 30ms;
        const auto record = [&](int which) {
            std::lock_guard lock(mutex);
            woken.emplace_back(which, std::chrono::steady_clock::now());
            if (woken.size() == 2) both.set_value();
        };
        loop.wait(-1, second_due, [record] { record(2); });
        loop.wait(-1, first_due, [record] { record(1); });
    });
    ASSERT_EQ(both.get_future().wait_for(30s), std::future_status::ready);
    std::lock_guard lock(mutex);
    EXPECT_EQ(woken[0].first, 1);
    EXPECT_EQ(woken[1].first, 2);
    EXPECT_GE(woken[0].second, first_due);
    EXPECT_GE(woken[1].second, second_due);
}

// A cancelled wait never runs; a wait whose descriptor is readable and whose deadline has
// passed runs once.
TEST(LineLoop, ACancelledWaitNeverWakesAndAWaitWakesOnce) {
    LineLoop loop;
    Pipe pipe;
    ASSERT_EQ(::write(pipe.ends[1], "x", 1), 1);  // readable from the start, and stays so
    int cancelled_runs = 0;
    int kept_runs = 0;
    on_loop(loop, [&] {
        const auto id = loop.wait(pipe.ends[0], std::chrono::steady_clock::now(), [&] { ++cancelled_runs; });
        loop.wait(pipe.ends[0], std::chrono::steady_clock::now(), [&] { ++kept_runs; });
        loop.cancel(id);
    });
    // Two more turns of the loop, with a deadline wait between them.
    std::promise<void> turned;
    on_loop(loop, [&] { loop.wait(-1, std::chrono::steady_clock::now() + 20ms, [&] { turned.set_value(); }); });
    ASSERT_EQ(turned.get_future().wait_for(30s), std::future_status::ready);
    on_loop(loop, [] {});
    EXPECT_EQ(cancelled_runs, 0);
    EXPECT_EQ(kept_runs, 1);
}

// On a VirtualClock the loop never sleeps on a deadline: idle, it moves the clock to the
// earliest one, so a day of deadlines passes at once and each wakes at its exact instant. While
// a hold lives (another thread working for the lines), the clock stands still.
TEST(LineLoop, OnAVirtualClockIdleTimeJumpsToTheNextDeadlineUnlessHeld) {
    auto clock = std::make_shared<VirtualClock>();
    LineLoop loop(clock);
    const Instant start = clock->now();
    std::promise<std::vector<Instant>> woke;
    on_loop(loop, [&] {
        auto times = std::make_shared<std::vector<Instant>>();
        for (const Instant::duration after : {Instant::duration(24h), Instant::duration(1h), Instant::duration(1ms)}) {
            loop.wait(-1, start + after, [&, times] {
                times->push_back(clock->now());
                if (times->size() == 3) woke.set_value(*times);
            });
        }
    });
    auto future = woke.get_future();
    ASSERT_EQ(future.wait_for(30s), std::future_status::ready) << "a day of virtual time did not pass in 30 s";
    EXPECT_EQ(future.get(), (std::vector<Instant>{start + 1ms, start + 1h, start + 24h}));

    std::shared_ptr<void> hold = loop.hold_time();
    ASSERT_NE(hold, nullptr);
    std::promise<void> later;
    on_loop(loop, [&] { loop.wait(-1, clock->now() + 1s, [&] { later.set_value(); }); });
    auto future_later = later.get_future();
    EXPECT_EQ(future_later.wait_for(200ms), std::future_status::timeout) << "the time moved while held";
    EXPECT_EQ(clock->now(), start + 24h);
    hold.reset();
    ASSERT_EQ(future_later.wait_for(30s), std::future_status::ready) << "the time did not move once let go";
    EXPECT_EQ(clock->now(), start + 24h + 1s);
    EXPECT_EQ(LineLoop().hold_time(), nullptr);  // steady time: nothing to hold
}

}  // namespace
}  // namespace loopwire::session
