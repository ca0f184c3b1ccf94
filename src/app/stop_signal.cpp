#include "app/stop_signal.hpp"

#include <csignal>
#include <ctime>

#include "common/thread_name.hpp"

namespace loopwire::app {

namespace {
sigset_t handled_signals(bool hangup) {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    if (hangup) sigaddset(&set, SIGHUP);
    return set;
}
}  // namespace

StopSignal::StopSignal(std::optional<std::chrono::microseconds> limit, std::function<void()> on_hangup, Waits waits)
    : signals_(handled_signals(static_cast<bool>(on_hangup))),
      deadline_(limit ? std::optional(std::chrono::steady_clock::now() + *limit) : std::nullopt),
      on_hangup_(std::move(on_hangup)) {
    pthread_sigmask(SIG_BLOCK, &signals_, nullptr);
    if (waits == Waits::caller) return;
    waiter_ = std::jthread([this](std::stop_token own) {
        while (!own.stop_requested() && !source_.stop_requested()) take_signal();
        source_.request_stop();
    });
    name_thread(waiter_.native_handle(), "lw-signals");
}

void StopSignal::wait(const std::stop_token& until) {
    while (!until.stop_requested() && !source_.stop_requested()) take_signal();
}

void StopSignal::take_signal() {
    const timespec tick{0, 50'000'000};
    const int received = sigtimedwait(&signals_, nullptr, &tick);
    if (received == SIGHUP) {
        on_hangup_();
        return;
    }
    if (received > 0) stopped_by_signal_ = true;
    if (received > 0 || (deadline_ && std::chrono::steady_clock::now() >= *deadline_)) source_.request_stop();
}

StopSignal::~StopSignal() {
    if (waiter_.joinable()) {
        waiter_.request_stop();
        waiter_.join();
    }
    // A stop signal sent twice (timeout(1) signals its child and then its whole process group)
    // would otherwise stay pending and kill the process the moment it is unblocked, at the end
    // of a clean shutdown: the stop was asked for and done, so the repeats are consumed here.
    const timespec now{0, 0};
    while (sigtimedwait(&signals_, nullptr, &now) > 0) {
    }
    // A stop that came by signal leaves them blocked: on a loaded machine timeout(1)'s second
    // signal can come after the drain above, and unblocked it killed a gateway that had stopped
    // cleanly (exit 143 instead of 0). The command returns once this object goes, so nothing
    // is left for a later Ctrl-C to interrupt.
    if (!stopped_by_signal_) pthread_sigmask(SIG_UNBLOCK, &signals_, nullptr);
}

}  // namespace loopwire::app
