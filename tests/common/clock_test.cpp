// The clocks the sessions run on (common/clock.hpp).
#include "common/clock.hpp"

#include <gtest/gtest.h>

namespace loopwire {
namespace {

using namespace std::chrono_literals;

TEST(VirtualClock, StandsStillUntilSomebodySleepsOrAdvancesIt) {
    VirtualClock clock;
    const Instant start = clock.now();
    EXPECT_EQ(clock.now(), start);
    clock.sleep_for(1500ms);
    EXPECT_EQ(clock.now() - start, 1500ms);
    clock.advance(250ms);
    EXPECT_EQ(clock.now() - start, 1750ms);
}

TEST(VirtualClock, SleepingUntilAPastInstantLeavesTimeWhereItIs) {
    VirtualClock clock;
    const Instant start = clock.now();
    clock.sleep_until(start - 10ms);
    clock.sleep_until(Instant{});  // "never", as a default-constructed instant, lies in the past
    clock.advance(-5ms);           // time does not run backwards
    EXPECT_EQ(clock.now(), start);
}

TEST(SteadyClock, SleepsInWallTime) {
    const auto clock = steady_clock();
    const Instant start = clock->now();
    const auto wall_start = std::chrono::steady_clock::now();
    clock->sleep_for(20ms);
    EXPECT_GE(clock->now() - start, 20ms);
    EXPECT_GE(std::chrono::steady_clock::now() - wall_start, 20ms);
}

}  // namespace
}  // namespace loopwire
