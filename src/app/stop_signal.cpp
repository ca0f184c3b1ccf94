#include "app/stop_signal.hpp"

#include <csignal>
#include <ctime>

namespace loopwire::app {

namespace {
sigset_t stop_signals() {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    return set;
}
}  // namespace

StopSignal::StopSignal(std::optional<std::chrono::microseconds> limit) {
    const sigset_t set = stop_signals();
    pthread_sigmask(SIG_BLOCK, &set, nullptr);
    const auto deadline = limit ? std::optional(std::chrono::steady_clock::now() + *limit) : std::nullopt;
    waiter_ = std::jthread([this, set, deadline](std::stop_token own) {
        const timespec tick{0, 50'000'000};
        while (!own.stop_requested() && !source_.stop_requested()) {
            if (sigtimedwait(&set, nullptr, &tick) > 0) break;
            if (deadline && std::chrono::steady_clock::now() >= *deadline) break;
        }
        source_.request_stop();
    });
}

StopSignal::~StopSignal() {
    waiter_.request_stop();
    waiter_.join();
    const sigset_t set = stop_signals();
    pthread_sigmask(SIG_UNBLOCK, &set, nullptr);
}

}  // namespace loopwire::app
