#pragma once
// A gateway line's link that comes back by itself. The master of a line is opened through this
// wrapper, which owns "open, use, and on a link failure close and open again later": a port that
// hangs up or fails (EIO, ENXIO or end-of-file on a pseudo-terminal whose program went away, a
// USB-RS485 adapter pulled out, a device server that dropped the connection) is closed, and the
// line is down until it opens again. While it is down every request fails at once with
// "line NAME (LINK) is down: REASON; retrying in N s" (ErrorKind::link), without waiting for the
// wire. The first request after the wait has passed is the one that reopens it: 1 s after the
// failure, then waits doubling to 30 s, forever (the gateway's polls ask at least once per poll
// interval). A port missing when the gateway starts is simply a line that starts down.
//
// Logged once per change of state, not per try: down (with the reason), still down for another
// reason, up again (how long it was down, how many tries it took).
//
// Time runs on the injected Clock, so the reopen schedule is tested in virtual time.
//
// Threads: requests are carried one at a time by the wrapper's own worker thread, through the
// opened master's blocking calls, so the opened master can be closed on that thread; completions
// run there too, or on the caller's thread for a request refused at once while the line is down.
// Like the serial master, it joins its worker when destroyed: never destroy it from a completion.
//
// On a loop (LinkConcurrency::on_loop, a master carried by the lines' shared loop,
// session/line_loop.hpp: a serial one, or a Modbus TCP one whose connection is read there; the
// gateway's lines are all so): requests go to the opened master as in the concurrent case below
// (it queues them on the loop, or writes them, and never waits for the reply), several at once
// if the master takes them, and the worker thread exists only while
// there is work for it: reopening the line, or closing a master that failed. So a line that is
// up costs no thread of its own. The request that reopens the line is handed to the opened
// master as a direct one, and the loop's time (when virtual, in a soak) is held from the moment
// the request is handed to the worker until then, so the lines' time does not run on while the
// worker opens (LineLoop::hold_time).
//
// Concurrent (LinkConcurrency::several, a master that pairs replies by transaction id and runs
// off any loop of the caller's): while the line is up, *_async calls go straight to the opened
// master, several at once, and their completions run on its thread. A link failure one of them meets is handed to the
// worker, which closes the master once no caller is inside it any more; requests sent meanwhile
// go by the worker and are refused while the line is down. Opening, and every request while the
// line is down or failing, still take the worker's one-at-a-time path.
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "common/clock.hpp"
#include "common/result.hpp"
#include "session/line_loop.hpp"
#include "session/master.hpp"

namespace loopwire::gateway {

struct ReopenSchedule {
    std::chrono::milliseconds first{1000};  // after the failure or the first refused open
    std::chrono::milliseconds max{30000};   // the doubling stops here
};

// What a line's link has been through (for the statistics, /metrics and the log).
struct LinkHealth {
    bool up = false;
    std::string reason;                  // why it is down; empty while up
    std::chrono::milliseconds retry_in{0};  // while down: until the next reopen may be tried
    std::uint64_t down_periods = 0;      // times the line went down (a start without it counts)
    std::uint64_t reopen_attempts = 0;   // opens tried after the first, failed or not
    std::uint64_t reopened = 0;          // of those, the ones that succeeded
    std::uint64_t refused_while_down = 0;  // requests failed at once, never sent
    std::chrono::microseconds down_time{0};  // time spent down, the current period included
};

// Opens the line's master: the serial port, the connection, or an attachment to a virtual bus.
// ErrorKind::usage means the configuration itself is wrong (a baud rate the port cannot have):
// that is not retried.
using MasterOpener = std::function<Result<std::unique_ptr<session::Master>>()>;

// Whether the opened master may carry several requests at once (LineSchedulerOptions::max_in_flight),
// or one at a time on a loop shared with other lines (MasterOptions::loop); both take requests
// directly, without the worker.
enum class LinkConcurrency { one, several, on_loop };

// The gateway's log (gateway/forwarding_unit.hpp's GatewayLog has the same shape).
using LinkLog = std::function<void(const std::string&)>;

class ReopeningMaster final : public session::Master {
public:
    // `name` and `link` are the line's, for messages: "line furnace (rtu:/dev/ttyUSB0?...)".
    // `loop`: the loop the opened masters run on (LinkConcurrency::on_loop only).
    ReopeningMaster(std::string name, std::string link, MasterOpener open, ReopenSchedule schedule = {},
                    std::shared_ptr<Clock> clock = steady_clock(), LinkLog log = {},
                    LinkConcurrency concurrency = LinkConcurrency::one, std::shared_ptr<session::LineLoop> loop = nullptr);
    ~ReopeningMaster() override;

    // The first open, when the gateway starts. A link error leaves the line down (logged, and
    // retried as above) and is not returned; only a usage error is, since retrying cannot help.
    Result<void> start();

    Result<codec::Reply> execute(std::uint8_t unit, const codec::Request& request) override;
    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override;
    Result<Bytes> forward(std::uint8_t unit, ByteView pdu) override;
    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override;
    std::string describe() const override { return link_; }
    // What the open master carries ends now, and every request from now on is refused (both
    // marked abandoned: no line goes down, no device is told anything), for a gateway that stops.
    void close() override;

    LinkHealth health() const;

private:
    struct State;

    std::string link_;
    LinkConcurrency concurrency_;
    std::unique_ptr<State> state_;
};

}  // namespace loopwire::gateway
