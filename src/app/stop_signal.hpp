#pragma once
// Turns Ctrl-C / SIGTERM (and an optional time limit) into a std::stop_token, so long-running
// commands end cleanly: sockets closed, pseudo-terminal links removed. Given `on_hangup`,
// SIGHUP calls it (on this object's thread) instead of killing the process: how a service is
// asked to re-read its configuration.
#include <csignal>
#include <chrono>
#include <functional>
#include <optional>
#include <stop_token>
#include <thread>

namespace loopwire::app {

class StopSignal {
public:
    // Construct before starting other threads: they inherit the blocked signals, so only this
    // object's thread receives them.
    explicit StopSignal(std::optional<std::chrono::microseconds> limit = std::nullopt,
                        std::function<void()> on_hangup = {});
    ~StopSignal();
    StopSignal(const StopSignal&) = delete;
    StopSignal& operator=(const StopSignal&) = delete;

    std::stop_token token() const { return source_.get_token(); }
    void request_stop() { source_.request_stop(); }

private:
    std::stop_source source_;
    sigset_t signals_;
    std::jthread waiter_;
};

}  // namespace loopwire::app
