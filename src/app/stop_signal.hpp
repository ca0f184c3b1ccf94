#pragma once
// Turns Ctrl-C / SIGTERM (and an optional time limit) into a std::stop_token, so long-running
// commands end cleanly: sockets closed, pseudo-terminal links removed. Given `on_hangup`,
// SIGHUP calls it instead of killing the process: how a service is asked to re-read its
// configuration.
//
// Who takes the signals: a thread of this object's own (Waits::own_thread), or the caller's
// thread while it waits in wait() (Waits::caller: the gateway's serving thread, which has
// nothing else to do meanwhile, so no thread is kept for signals alone). Either way the
// signals are blocked in every thread and taken with sigtimedwait, never in a handler.
#include <atomic>
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
    enum class Waits { own_thread, caller };

    explicit StopSignal(std::optional<std::chrono::microseconds> limit = std::nullopt,
                        std::function<void()> on_hangup = {}, Waits waits = Waits::own_thread);
    ~StopSignal();
    StopSignal(const StopSignal&) = delete;
    StopSignal& operator=(const StopSignal&) = delete;

    std::stop_token token() const { return source_.get_token(); }
    void request_stop() { source_.request_stop(); }

    // Waits::caller: takes the signals on this thread (on_hangup runs here) until `until` or this
    // object's own token is stopped.
    void wait(const std::stop_token& until);

private:
    // Waits up to 50 ms for one signal and acts on it; asks for the stop when the limit passed.
    void take_signal();

    std::stop_source source_;
    sigset_t signals_;
    std::optional<std::chrono::steady_clock::time_point> deadline_;
    std::function<void()> on_hangup_;
    std::atomic<bool> stopped_by_signal_{false};  // SIGINT or SIGTERM came (not the time limit)
    std::jthread waiter_;
};

}  // namespace loopwire::app
