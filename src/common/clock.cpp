#include "common/clock.hpp"

#include <algorithm>
#include <thread>

namespace loopwire {
namespace {

class SteadyClock final : public Clock {
public:
    Instant now() const override { return std::chrono::steady_clock::now(); }
    void sleep_until(Instant deadline) override { std::this_thread::sleep_until(deadline); }
};

}  // namespace

std::shared_ptr<Clock> steady_clock() {
    return std::make_shared<SteadyClock>();  // stateless: no shared instance needed
}

Instant VirtualClock::now() const {
    std::lock_guard lock(mutex_);
    return now_;
}

void VirtualClock::sleep_until(Instant deadline) {
    std::lock_guard lock(mutex_);
    now_ = std::max(now_, deadline);
}

void VirtualClock::advance(Instant::duration length) {
    std::lock_guard lock(mutex_);
    now_ += std::max(length, Instant::duration::zero());
}

}  // namespace loopwire
