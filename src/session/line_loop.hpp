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
// Time is the steady clock: the loop sleeps in ppoll, which knows no other.
#include <cstdint>
#include <functional>
#include <memory>

#include "common/bytes.hpp"

namespace loopwire::session {

class LineLoop {
public:
    LineLoop();  // starts the thread, named lw-lines
    // Stops and joins the thread; what is still posted or waiting is dropped unrun. Whatever
    // posted work or waits here (serial masters) must be gone before.
    ~LineLoop();
    LineLoop(const LineLoop&) = delete;
    LineLoop& operator=(const LineLoop&) = delete;

    // Runs `job` on the loop's thread, after the jobs posted before it. From any thread.
    void post(std::function<void()> job);
    bool on_loop_thread() const;

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
