#pragma once
// One thread that carries every serial line of a gateway (docs/DESIGN.md, gateway: the thread
// count does not grow with lines). A serial master given a LineLoop (MasterOptions::loop) runs
// its exchanges as coroutines (common/task.hpp) that suspend where a blocking master would
// wait: for bytes or a deadline on its stream, or for time alone (silences, turnarounds, a
// frame's wire time). The loop waits in ppoll() on all of them at once and resumes each when its
// stream is readable or its deadline has passed, so a line waiting out a 1 s timeout never
// delays a reply on another.
//
// Level-triggered on purpose: a stream's poll handle may stay readable while bytes are left
// unread (a virtual bus port's timerfd does), and an edge-triggered reactor would never wake
// for them again.
//
// Time is the steady clock, unless a VirtualClock is given: the loop then never sleeps on a
// deadline. Whenever it is idle (nothing posted, no stream readable), it moves the clock to the
// earliest deadline at once, so hours of a line's plant time (polls, timeouts, back-offs, the
// simulated devices' replies) pass in seconds. That is exact only while everything that runs
// on that time is carried by this loop and its streams are readable exactly when the clock
// says (a stream in virtual time makes its handle readable from a wait on this loop); work
// another thread posts meanwhile comes in when it comes, at whatever the clock says then.
#include <cstdint>
#include <functional>
#include <memory>

#include "common/bytes.hpp"
#include "common/clock.hpp"

namespace loopwire::session {

class LineLoop {
public:
    LineLoop();  // starts the thread, named lw-lines; steady time
    explicit LineLoop(std::shared_ptr<VirtualClock> clock);  // virtual time (above)
    // Stops and joins the thread; what is still posted or waiting is dropped unrun. Whatever
    // posted work or waits here (serial masters) must be gone before.
    ~LineLoop();
    LineLoop(const LineLoop&) = delete;
    LineLoop& operator=(const LineLoop&) = delete;

    // Runs `job` on the loop's thread, after the jobs posted before it. From any thread.
    void post(std::function<void()> job);
    bool on_loop_thread() const;

    // The time of every deadline given to wait(): what whoever waits here reads the time from.
    const std::shared_ptr<Clock>& clock() const;

    // Virtual time only (null in steady time): while the returned hold lives, the clock stays
    // where it is, and the loop runs only what is posted and what its streams bring. For work
    // another thread does for the loop's lines (a line being reopened by its worker), which the
    // lines' time must not run past. Let it go before waiting for anything that takes time on
    // the loop, or the loop waits for ever.
    std::shared_ptr<void> hold_time();

    using WaitId = std::uint64_t;
    // On the loop's thread only: `wake` runs once, on the loop, when `fd` is readable (or has
    // an error or hang-up, which its next read reports) or `deadline` has passed, whichever
    // comes first. fd -1: the deadline alone.
    WaitId wait(int fd, Instant deadline, std::function<void()> wake);
    // On the loop's thread only: the wait will not wake (no-op if it already has).
    void cancel(WaitId id);

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace loopwire::session
