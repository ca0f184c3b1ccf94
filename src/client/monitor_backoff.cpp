#include "client/monitor_backoff.hpp"

#include <algorithm>

namespace loopwire::device {

RetryBackoff::RetryBackoff(std::chrono::milliseconds first, std::chrono::milliseconds cap)
    : first_(std::max(first, std::chrono::milliseconds(1))), cap_(std::max(cap, first_)) {}

void RetryBackoff::failed(Clock::time_point now) {
    ++failures_;
    // Doubling stops at the cap, so the wait never overflows however long the unit stays dead.
    wait_ = failures_ == 1 ? first_ : std::min(cap_, wait_ * 2);
    next_try_ = now + wait_;
}

void RetryBackoff::succeeded() {
    failures_ = 0;
    wait_ = std::chrono::milliseconds(0);
    next_try_ = Clock::time_point{};
}

}  // namespace loopwire::device
