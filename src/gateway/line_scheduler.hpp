#pragma once
// One serial line (or one-connection TCP device) shared by everything that wants it: one request
// on the wire at a time (a Modbus TCP device that takes several at once: up to max_in_flight,
// told apart by transaction id). Writes go first. Clients' requests and the gateway's own polls then
// share the line by turns: while both are waiting, they alternate (after a client's request the
// oldest waiting poll goes, after a poll the next client's), and whichever is alone takes every
// turn. Clients take turns among themselves (round robin), so a busy one cannot starve another.
//
// Why alternate: the pollers queue a request only when a poll is due and wait for its reply
// before the next, so they ask for no more than their configured rate; alternating means a poll
// waits for at most the request on the wire and one client's (plus any writes), however many
// clients keep the line busy. Polls therefore keep their rate as long as they need no more than
// half the line's turns, and clients always get at least half when they want it; a line whose
// polls need more falls behind, which the poll groups report (poll_groups.hpp). Strict priority
// for clients, as before, let ten clients reading back to back hold every poll for minutes.
//
// A request whose deadline has passed or whose client has gone is never sent (docs/DESIGN.md,
// gateway).
//
// The back-off of a unit lives here and nowhere else: only the outcomes of Priority::poll
// requests move it (a timeout doubles it, 1 s to 30 s; an answer clears it), so a client's
// request the unit ignores costs that client a 0Bh and nothing more, and a unit that stopped
// answering costs the others at most one timeout per back-off period. The gateway's poller keeps
// no back-off of its own: it asks hold_poll() before each poll (client/monitor_loop.hpp,
// MonitorTarget::held_until). A link failure clears every unit's back-off: the line was at
// fault, and when it is back every unit is polled at once.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>

#include "common/bytes.hpp"
#include "common/clock.hpp"
#include "common/result.hpp"
#include "session/master.hpp"
#include "session/unit_handler.hpp"

namespace loopwire::gateway {

enum class Priority { write, client, poll };  // writes first; clients and polls by turns

struct LineRequest {
    std::uint8_t unit = 1;
    Bytes pdu;
    Priority priority = Priority::client;
    std::uint64_t client = 0;  // who asked; fairness is round robin between clients
    Instant deadline = Instant::max();  // not sent once this has passed
    // Optional: false once the asker has gone (read with the scheduler's lock held when the
    // queue is full, to make room).
    session::UnitHandler::WantedFlag still_wanted;
    session::Master::ForwardCompletion done;  // the reply PDU, or why there is none

    bool wanted() const { return session::UnitHandler::wanted(still_wanted); }
};

struct LineSchedulerOptions {
    std::chrono::milliseconds first_backoff{1000};
    std::chrono::milliseconds max_backoff{30000};
    // Writes and clients' requests queued at once (polls are the gateway's own and bounded by
    // their groups). Past it, once requests nobody waits for any more are dropped, a request is
    // refused at once with exception 06h, "server device busy" (Modbus application protocol
    // V1.1b3, 7: "the client should retransmit the message later"). Not 0Bh: the device is
    // answering, it is the gateway's queue that is full, and a client must not conclude that
    // the device is gone. Not 0Ah either: that one is this gateway's answer for a unit no line
    // leads to, a configuration mistake. 256 requests take a 19200-baud line some 5 s or more,
    // past what a Modbus TCP client waits.
    std::size_t max_queued = 256;
    // Requests on the wire at once. 1 for a serial line, where one reply must come (or time out)
    // before the next request. More only for a master that pairs replies with requests by
    // transaction id (Modbus TCP); the next request then goes while earlier ones are answered,
    // in the same order of turns.
    std::size_t max_in_flight = 1;
};

// The exception code of the refusal above; the error has ErrorKind::exception and this code.
constexpr int server_device_busy = 0x06;

struct LineStatistics {
    std::uint64_t sent = 0;          // requests put on the wire
    std::uint64_t polls_sent = 0;    // of which the gateway's own polls
    std::uint64_t answered = 0;      // replies, exception replies included
    std::uint64_t timeouts = 0;
    std::uint64_t bad_replies = 0;   // malformed or mismatched replies
    std::uint64_t expired = 0;       // dropped unsent: deadline passed
    std::uint64_t abandoned = 0;     // dropped unsent: the asker had gone
    std::uint64_t backed_off = 0;    // polls held back or refused: the unit is backing off
    std::uint64_t refused_busy = 0;  // refused unqueued: max_queued were waiting
    std::size_t queued = 0;          // waiting now
    bool on_wire = false;            // a request is on the line now
    std::size_t asked = 0;           // clients' requests and writes queued or on the line now
    std::size_t in_flight = 0;       // how many (at most max_in_flight)
    // How long the line has carried at least one request (from sending to its outcome) and how
    // long the scheduler has existed: busy / open is the line's utilisation.
    std::chrono::microseconds busy{0};
    std::chrono::microseconds open{0};
};

// Ownership: keep your own reference to the master and destroy the scheduler first, then the
// master (declare the master before the scheduler). The serial master joins its thread when it
// is destroyed, so it must never be destroyed on that thread, which is where completions and
// `done` run; if the scheduler held the last reference, destroying the scheduler inside a
// `done` would do exactly that. A request in flight when the scheduler goes still ends: its
// `done` runs with the master's result whenever that arrives, without touching the scheduler.
// `done` must not throw.
class LineScheduler {
public:
    LineScheduler(std::shared_ptr<session::Master> master, LineSchedulerOptions options = {},
                  std::shared_ptr<Clock> clock = steady_clock());
    // Fails what is still queued (ErrorKind::link, "gateway stopping") and lets go of the
    // master; does not wait for the request in flight.
    ~LineScheduler();
    LineScheduler(const LineScheduler&) = delete;
    LineScheduler& operator=(const LineScheduler&) = delete;

    // Queues a request; `done` runs exactly once, on the master's thread or the caller's.
    void submit(LineRequest request);

    LineStatistics statistics() const;

    // For the poller, before it polls `unit`: when the unit's polls are backing off, when the
    // next one may go (and the poll is counted as held back); nothing when it may go now.
    std::optional<Instant> hold_poll(std::uint8_t unit);

    // A reload keeps the line for the next gateway (gateway/line_keeper.hpp): every request queued
    // or on the wire is answered now (ErrorKind::link, "gateway reloading"), so the gateway going
    // away waits for none, and every request is refused so until resume(). A request on the wire
    // stays there until its reply or timeout; its outcome counts for the line (statistics,
    // back-off) and reaches no one. The statistics and back-offs carry on across.
    void hand_over();
    void resume();

private:
    struct State;
    std::shared_ptr<State> state_;
};

}  // namespace loopwire::gateway
