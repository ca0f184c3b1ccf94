#pragma once
// The time the session state machines run on: the 3.5-character silence before a frame, the
// reply timeout, the broadcast turnaround and the slave's reply gap. Injected, as the
// simulators' clocks are (docs/DESIGN.md: "time and randomness are injected so tests are
// deterministic"), so tests of timeouts and retries run in virtual time instead of wall time.
//
// Why this shape:
// - Two operations are enough: now(), and sleep_until(), the only way the session code waits
//   for time alone. Waiting for bytes *or* a deadline is a ByteStream's read_some(timeout); a
//   stream that runs on a virtual clock turns that wait into a jump too (the tests' scripted
//   streams do), so a timeout expires when virtual time passes the deadline with nothing
//   delivered, and a reply due before it arrives at its exact virtual instant.
// - VirtualClock jumps: sleeping until an instant moves time there at once. That is exact when
//   one thread drives the session and everything it waits for is scheduled on the same clock,
//   which is how the virtual-time tests are built (a master against a scripted stream, a
//   slave's serve_stream against a scripted line, each on the test's thread).
// - The lines' loop (session/line_loop.hpp) on a VirtualClock is the exception: every line and
//   its simulated devices run on that one thread, so it moves the clock only when it is idle
//   (the gateway's line soak, tests/gateway/line_soak_test.cpp, runs a day of four lines so).
// - The virtual bus (transport/virtual_bus.hpp) keeps wall time. Its stations run on separate
//   threads; a clock that jumps when one thread sleeps would expire another thread's deadline
//   while that thread is still working, a timeout that no real line would produce. Virtual time
//   across threads needs a clock that advances only once every thread is idle, which means
//   every thread and every blocking call (mutexes included) reporting to it; that costs more
//   than the seconds it would save, so the bus, and the fault schedules run on it, stay on
//   the steady clock.
#include <chrono>
#include <memory>
#include <mutex>

#include "common/bytes.hpp"

namespace loopwire {

class Clock {
public:
    virtual ~Clock() = default;
    Clock() = default;
    Clock(const Clock&) = delete;
    Clock& operator=(const Clock&) = delete;

    virtual Instant now() const = 0;
    // Returns once now() has reached `deadline` (at once if it already has).
    virtual void sleep_until(Instant deadline) = 0;

    void sleep_for(Instant::duration length) { sleep_until(now() + length); }
};

// The process's steady clock: what every session runs on unless a test injects another.
std::shared_ptr<Clock> steady_clock();

// Virtual time for tests: it stands still until someone sleeps or advances it. Starts an hour
// past the epoch so that a default-constructed Instant ("never") lies in the past, as it does
// on the steady clock. Safe to share between threads, but see above for what it models.
class VirtualClock final : public Clock {
public:
    VirtualClock() = default;

    Instant now() const override;
    void sleep_until(Instant deadline) override;  // jumps there, if that is later than now
    void advance(Instant::duration length);

private:
    mutable std::mutex mutex_;
    Instant now_ = Instant{} + std::chrono::hours(1);
};

}  // namespace loopwire
