#pragma once
// What the gateway's polls need of the loop they run on (gateway/poll_groups.hpp): work posted
// from any thread, timers on the loop's clock, the time, and a way to take a part down while the
// loop goes on for the others. The gateway's Engine is one (Boost.Asio, the steady clock);
// LineLoopEvents puts the same parts on a session::LineLoop, whose clock may be virtual, so that
// a test runs the polls with the lines under them on one clock, hours of plant time in seconds
// (tests/gateway/line_soak_test.cpp).
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>

#include "common/clock.hpp"

namespace loopwire::session {
class LineLoop;
}

namespace loopwire::gateway {

class EventLoop {
public:
    using TimerId = std::uint64_t;

    virtual ~EventLoop() = default;

    // Runs `work` on the loop's thread, after what was posted before it. From any thread.
    virtual void post(std::function<void()> work) = 0;
    // On the loop's thread only: `work` runs there, once, when the clock has reached `when`,
    // unless cancelled first. A cancelled timer never runs, even one already due.
    virtual TimerId at(Instant when, std::function<void()> work) = 0;
    virtual void cancel(TimerId id) = 0;  // on the loop's thread; no-op once it has run
    // What the timers run on, and what the parts read the time from.
    virtual const std::shared_ptr<Clock>& clock() const = 0;
    // The wall-clock time of clock()'s now: what samples are stamped with.
    virtual std::chrono::system_clock::time_point wall_now() const = 0;
    // Runs `work` on the loop's thread after everything posted before it, and returns once it
    // has run (here, when the loop has stopped). Never from the loop's own thread.
    virtual void take_down(const std::function<void()>& work) = 0;
};

// One timer on an EventLoop, used on the loop's thread only: setting it again replaces what
// was set, and destroying it cancels it.
class LoopTimer {
public:
    explicit LoopTimer(EventLoop& loop) : loop_(loop) {}
    ~LoopTimer() { cancel(); }
    LoopTimer(const LoopTimer&) = delete;
    LoopTimer& operator=(const LoopTimer&) = delete;

    void set(Instant when, std::function<void()> work);
    void cancel();

private:
    EventLoop& loop_;
    std::optional<EventLoop::TimerId> id_;
};

// The EventLoop of a session::LineLoop: its thread, its clock (steady or virtual). Stamps wall
// time as the system clock read at construction plus the loop's time since.
class LineLoopEvents final : public EventLoop {
public:
    explicit LineLoopEvents(std::shared_ptr<session::LineLoop> loop);

    void post(std::function<void()> work) override;
    TimerId at(Instant when, std::function<void()> work) override;
    void cancel(TimerId id) override;
    const std::shared_ptr<Clock>& clock() const override;
    std::chrono::system_clock::time_point wall_now() const override;
    void take_down(const std::function<void()>& work) override;

private:
    std::shared_ptr<session::LineLoop> loop_;
    Instant started_;
    std::chrono::system_clock::time_point wall_started_;
};

}  // namespace loopwire::gateway
