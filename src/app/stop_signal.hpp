#pragma once
// Turns Ctrl-C / SIGTERM (and an optional time limit) into a std::stop_token, so long-running
// commands end cleanly: sockets closed, pseudo-terminal links removed.
#include <chrono>
#include <optional>
#include <stop_token>
#include <thread>

namespace loopwire::app {

class StopSignal {
public:
    // Construct before starting other threads: they inherit the blocked SIGINT/SIGTERM mask, so
    // only this object's thread receives them.
    explicit StopSignal(std::optional<std::chrono::microseconds> limit = std::nullopt);
    ~StopSignal();
    StopSignal(const StopSignal&) = delete;
    StopSignal& operator=(const StopSignal&) = delete;

    std::stop_token token() const { return source_.get_token(); }
    void request_stop() { source_.request_stop(); }

private:
    std::stop_source source_;
    std::jthread waiter_;
};

}  // namespace loopwire::app
