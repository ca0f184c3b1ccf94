#pragma once
// When to try a device again that stopped answering: exponential back-off, so a dead unit costs
// at most one timeout per back-off period and never slows the units that do answer.
#include <chrono>

namespace loopwire::device {

class RetryBackoff {
public:
    using Clock = std::chrono::steady_clock;

    // The first retry waits `first`; each further failure doubles the wait, up to `cap`.
    RetryBackoff(std::chrono::milliseconds first, std::chrono::milliseconds cap);

    bool due(Clock::time_point now) const { return now >= next_try_; }
    void failed(Clock::time_point now);
    void succeeded();

    unsigned consecutive_failures() const { return failures_; }
    std::chrono::milliseconds current_wait() const { return wait_; }
    Clock::time_point next_try() const { return next_try_; }

private:
    std::chrono::milliseconds first_;
    std::chrono::milliseconds cap_;
    std::chrono::milliseconds wait_{0};
    unsigned failures_ = 0;
    Clock::time_point next_try_{};
};

}  // namespace loopwire::device
