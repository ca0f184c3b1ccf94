#pragma once
// Waiting in a test for what another thread or process does: a connection accepted, a message
// seen, a count reached. The condition is asked again every few milliseconds until it holds or
// the patience runs out. The patience only bounds a hang: it is generous, as CI runs the suites
// under ASan and TSan on two loaded cores, and a test that finds it spent must fail saying what
// it waited for (ASSERT_TRUE(eventually(...)) << "what never happened").
#include <chrono>
#include <thread>

namespace loopwire::testing {

// Long enough for the slowest sanitizer build on a loaded machine; only a hang reaches it.
inline constexpr std::chrono::milliseconds default_patience = std::chrono::seconds(30);

// Whether `condition` holds before `patience` runs out, asked every `every`.
template <typename Condition>
bool eventually(Condition&& condition, std::chrono::milliseconds patience = default_patience,
                std::chrono::milliseconds every = std::chrono::milliseconds(5)) {
    const auto give_up = std::chrono::steady_clock::now() + patience;
    while (!condition()) {
        // One last look after the deadline: a thread descheduled past it still gets its answer.
        if (std::chrono::steady_clock::now() >= give_up) return condition();
        std::this_thread::sleep_for(every);  // polling a condition, not waiting for time to pass
    }
    return true;
}

}  // namespace loopwire::testing
