#include "gateway/reopening_master.hpp"

#include <algorithm>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <type_traits>
#include <utility>

#include <fmt/format.h>

#include "client/monitor_backoff.hpp"
#include "common/never_sent.hpp"
#include "session/job_queue.hpp"

namespace loopwire::gateway {
namespace {

// The reopen schedule runs on the injected clock; that only works while the back-off speaks of
// the same time points.
static_assert(std::is_same_v<Instant, device::RetryBackoff::Clock::time_point>);

std::string seconds_text(std::chrono::microseconds time) {
    return fmt::format("{:.1f} s", static_cast<double>(time.count()) / 1e6);
}

}  // namespace

struct ReopeningMaster::State {
    State(std::string line_name, std::string line_link, MasterOpener opener, ReopenSchedule chosen,
          std::shared_ptr<Clock> time, LinkLog logger, std::shared_ptr<session::LineLoop> lines_loop,
          session::JobQueue::WhenIdle worker_idle)
        : name(std::move(line_name)),
          link(std::move(line_link)),
          open(std::move(opener)),
          schedule(chosen),
          clock(std::move(time)),
          log(std::move(logger)),
          loop(std::move(lines_loop)),
          backoff(schedule.first, schedule.max),
          worker("lw-line " + name, worker_idle) {}

    // --- carrying requests (on the worker thread, or a caller of the blocking calls) ---------

    // Runs `call` on the line's master, opening it first when the line is down and a try is
    // due; a link failure takes the line down. One request at a time: the master is never
    // closed or replaced under a request.
    template <typename Call>
    auto carry(Call&& call) -> decltype(call(std::declval<session::Master&>())) {
        std::lock_guard carrying(use);
        auto line = ready();
        if (!line) return line.error();
        auto result = call(**line);
        if (!result && result.error().kind == ErrorKind::link && !abandoned(result.error())) return went_down(result.error());
        return result;
    }

    // The master to send on: the open one, or one opened now if the line is down and a try is
    // due; otherwise why not. With `use` held.
    Result<session::Master*> ready() {
        close_failing();
        {
            std::lock_guard lock(mutex);
            if (closing) return closing_error();
            if (master) return master.get();
            if (!backoff.due(clock->now())) return refuse();
        }
        return reopen();
    }

    // With `use` held, so that only one thread opens; `mutex` is not held while opening, so the
    // statistics and the refusals of requests stay quick however long an open takes.
    Result<session::Master*> reopen() {
        auto opened = open();
        std::lock_guard lock(mutex);
        ++counts.reopen_attempts;
        const auto now = clock->now();
        if (!opened) {
            backoff.failed(now);
            if (opened.error().message != reason) {
                reason = opened.error().message;
                say(fmt::format("warning: line {} ({}) is still down, now because: {}", name, link, reason));
            }
            return refuse();
        }
        master = std::move(*opened);
        ++generation;
        ++counts.reopened;
        const auto down_for = std::chrono::duration_cast<std::chrono::microseconds>(now - down_since);
        counts.down_time += down_for;
        // A notice: the end of the warning that said the line went down.
        say(fmt::format("notice: line {} ({}) is up again after {} down ({} reopen attempt{})", name, link, seconds_text(down_for),
                        attempts_this_period(), attempts_this_period() == 1 ? "" : "s"));
        reason.clear();
        backoff.succeeded();
        return master.get();
    }

    // The request that found the link failed: the line closes and is down from now on. The
    // master goes outside `mutex` (it may wait for its loop or thread), with `use` still held.
    Error went_down(const Error& failure) {
        std::unique_ptr<session::Master> closed;
        Error refused = failure;
        {
            std::unique_lock lock(mutex);
            no_senders.wait(lock, [this] { return senders == 0; });
            closed = std::move(master);
            failing = false;  // whatever a direct request found, it was this master: closed now
            mark_down(failure.message);
            refused = down_error();
        }
        closed.reset();
        return refused;
    }

    // With `mutex` held.
    void mark_down(std::string why, std::optional<Instant> since = std::nullopt) {
        const auto now = since ? *since : clock->now();
        reason = std::move(why);
        down_since = now;
        attempts_at_down = counts.reopen_attempts;
        ++counts.down_periods;
        backoff.failed(now);
        // A warning (GatewayLog): `journalctl -p warning` is where a person looks for a line gone.
        say(fmt::format("warning: line {} ({}) is down: {}; reopening it in {} s, then with back-off up to every {} s", name, link,
                        reason, std::chrono::ceil<std::chrono::seconds>(backoff.current_wait()).count(),
                        std::chrono::ceil<std::chrono::seconds>(schedule.max).count()));
    }

    // --- carrying several at once (LinkConcurrency::several) ---------------------------------

    // Hands the request to the open master from the caller's thread: `send(master, completion)`.
    // False, with nothing sent and `done` untouched, while the line is down or failing: the
    // request then takes the worker's path.
    template <typename Outcome, typename Send>
    bool send_directly(std::function<void(Outcome)>& done, Send send) {
        session::Master* line = nullptr;
        std::uint64_t opened_as = 0;
        {
            std::lock_guard lock(mutex);
            if (!master || failing || closing) return false;
            line = master.get();
            opened_as = generation;
            ++senders;
        }
        send(*line, [this, opened_as, done = std::move(done)](Outcome outcome) {
            if (!outcome && outcome.error().kind == ErrorKind::link && !abandoned(outcome.error())) {
                failed_underneath(opened_as, outcome.error());
            }
            done(std::move(outcome));
        });
        {
            std::lock_guard lock(mutex);
            --senders;
        }
        no_senders.notify_all();
        return true;
    }

    // On a loop: the worker opens the line (if a try is due) and hands the request to the opened
    // master as a direct one, which never waits on the loop; the loop's time stays held until
    // then. A request that finds the line down is refused as on the worker's path, its refusal
    // answered on the loop like every other outcome (what it starts next belongs there), and
    // posted before the time is let go: the plant time between the two is none.
    template <typename Outcome, typename Send>
    void reopen_and_send(std::function<void(Outcome)> done, Send send) {
        worker.push([this, done = std::move(done), send = std::move(send), hold = hold_for_reopen()]() mutable {
            const auto line = [this] {
                std::lock_guard carrying(use);
                return ready();
            }();
            if (!line) return answer_on_loop(std::move(done), line.error());
            if (!send_directly(done, std::move(send))) answer_on_loop(std::move(done), unavailable());
        });
    }

    template <typename Outcome>
    void answer_on_loop(std::function<void(Outcome)> done, Error error) {
        loop->post([done = std::move(done), error = std::move(error)] { done(error); });
    }

    // The loop's time, held while the worker opens a line that is down (nothing while it is up:
    // the request goes straight to the master then).
    std::shared_ptr<void> hold_for_reopen() {
        {
            std::lock_guard lock(mutex);
            if (master) return nullptr;
        }
        return hold_time();
    }

    // On a loop (in virtual time): the loop's time stands still until the holder lets go.
    std::shared_ptr<void> hold_time() const { return loop ? loop->hold_time() : nullptr; }

    // A request that comes once the line is closing: it tells nothing of its device.
    Error closing_error() const {
        return make_error(ErrorKind::link, fmt::format("line {} ({}) is closing", name, link), abandoned_code);
    }

    // Why a request just reopened for could not be sent: the master failed or is closing already.
    Error unavailable() {
        std::lock_guard lock(mutex);
        if (closing) return closing_error();
        if (!master) return refuse();
        return make_error(ErrorKind::link, fmt::format("line {} ({}) failed as it was reopened", name, link));
    }

    // A request sent directly met a link failure (on the master's thread, which must not close
    // its own master): the worker closes it.
    void failed_underneath(std::uint64_t opened_as, const Error& failure) {
        {
            std::lock_guard lock(mutex);
            if (closing || failing || !master || opened_as != generation) return;
            failing = true;
            failing_reason = failure.message;
            // The line went down now, not when the worker gets to close it: the back-off runs
            // from here (in virtual time the loop's clock may run on before the worker closes).
            failing_since = clock->now();
        }
        // On a loop the closing holds the loop's time, as a reopening does: requests are refused
        // until it is done, and in virtual time a loaded machine's worker took 350 s of plant
        // time to get to it, the line down all along (the soak's line back 197 s after its
        // outage). The master ends what it waits for at once when destroyed (~SerialMaster), so
        // it never waits for the held time.
        worker.push([this, hold = hold_time()] {
            std::lock_guard carrying(use);
            close_failing();
        });
    }

    // With `use` held: closes a master a direct request found failed, once no caller is inside
    // it, and the line is down from then on.
    void close_failing() {
        std::unique_ptr<session::Master> closed;
        {
            std::unique_lock lock(mutex);
            if (!failing) return;
            no_senders.wait(lock, [this] { return senders == 0; });
            failing = false;
            closed = std::move(master);
            mark_down(std::move(failing_reason), failing_since);
        }
        closed.reset();
    }

    // ReopeningMaster::close: what the open master carries ends now, and nothing more is sent.
    // The master's close runs outside `mutex`, counted as a sender so that it is not closed for
    // good under it: a TCP master fails what it awaits right there, and those completions may
    // hand the line its next request.
    void close_now() {
        session::Master* line = nullptr;
        {
            std::lock_guard lock(mutex);
            closing = true;
            if (!master) return;
            line = master.get();
            ++senders;
        }
        line->close();
        {
            std::lock_guard lock(mutex);
            --senders;
        }
        no_senders.notify_all();
    }

    // For the destructor, once the worker has finished: the master goes while this state is
    // whole, and completions it runs as it goes (a TCP master fails what it still awaits) hand
    // nothing to the worker.
    void close_for_good() {
        std::unique_ptr<session::Master> closed;
        {
            std::unique_lock lock(mutex);
            closing = true;
            no_senders.wait(lock, [this] { return senders == 0; });
            closed = std::move(master);
        }
        closed.reset();
    }

    // --- refusing while down ----------------------------------------------------------------

    // A request that would have to wait for a reopen that is not due yet is refused without
    // queueing for the worker: the caller hears at once.
    // So is one that comes while a master a request found failed waits for the worker to close
    // it: the line is down from that failure and no reopen can be due yet. Sent to the worker,
    // it held no time on a loop (the master was still there) and in virtual time waited for a
    // loaded machine's worker while the plant clock ran on: a line of the soak came back 13 min
    // of plant time after its outage instead of within one back-off.
    std::optional<Error> refusal() {
        std::lock_guard lock(mutex);
        if (master && failing) {
            ++counts.refused_while_down;
            return make_error(ErrorKind::link, fmt::format("line {} ({}) is down: {}; reopening it", name, link, failing_reason));
        }
        if (master || backoff.due(clock->now())) return std::nullopt;
        return refuse();
    }

    // With `mutex` held: a request that will not be sent because the line is down.
    Error refuse() {
        ++counts.refused_while_down;
        return down_error();
    }

    // With `mutex` held.
    Error down_error() const {
        const auto wait = backoff.next_try() - clock->now();
        const auto retry = std::max<long long>(1, std::chrono::ceil<std::chrono::seconds>(wait).count());
        return make_error(ErrorKind::link,
                          fmt::format("line {} ({}) is down: {}; retrying in {} s", name, link, reason, retry));
    }

    std::uint64_t attempts_this_period() const { return counts.reopen_attempts - attempts_at_down; }

    void say(const std::string& line) const {
        if (log) log(line);
    }

    LinkHealth health() const {
        std::lock_guard lock(mutex);
        LinkHealth now = counts;
        now.up = master != nullptr;
        if (!now.up) {
            const auto at = clock->now();
            now.reason = reason;
            now.retry_in = std::max(std::chrono::milliseconds(0),
                                    std::chrono::ceil<std::chrono::milliseconds>(backoff.next_try() - at));
            now.down_time += std::chrono::duration_cast<std::chrono::microseconds>(at - down_since);
        }
        return now;
    }

    const std::string name;
    const std::string link;
    const MasterOpener open;
    const ReopenSchedule schedule;
    const std::shared_ptr<Clock> clock;
    const LinkLog log;
    const std::shared_ptr<session::LineLoop> loop;  // on_loop: whose time a reopen holds

    std::mutex use;  // held while a request is carried or the line opened
    mutable std::mutex mutex;  // guards what follows
    std::unique_ptr<session::Master> master;  // null while the line is down
    std::uint64_t generation = 0;  // which opening `master` is: a failure of an earlier one is old news
    std::size_t senders = 0;       // callers inside master's *_async right now (concurrent path)
    std::condition_variable no_senders;
    bool failing = false;          // a direct request found the link failed; the worker closes it
    std::string failing_reason;
    Instant failing_since{};
    bool closing = false;          // the wrapper is being destroyed
    device::RetryBackoff backoff;  // the reopen schedule
    std::string reason;
    Instant down_since{};
    std::uint64_t attempts_at_down = 0;
    LinkHealth counts;  // the counters; up, reason and retry_in are filled in by health()
    session::JobQueue worker;  // last: stops (running what is queued) before the rest goes
};

ReopeningMaster::ReopeningMaster(std::string name, std::string link, MasterOpener open, ReopenSchedule schedule,
                                 std::shared_ptr<Clock> clock, LinkLog log, LinkConcurrency concurrency,
                                 std::shared_ptr<session::LineLoop> loop)
    : link_(link),
      concurrency_(concurrency),
      state_(std::make_unique<State>(std::move(name), std::move(link), std::move(open), schedule, std::move(clock),
                                     std::move(log), std::move(loop),
                                     concurrency == LinkConcurrency::on_loop ? session::JobQueue::WhenIdle::end_thread
                                                                             : session::JobQueue::WhenIdle::keep_thread)) {}

void ReopeningMaster::close() { state_->close_now(); }

ReopeningMaster::~ReopeningMaster() {
    state_->worker.finish();  // what is queued is carried on the open master, as it was asked
    state_->close_for_good();
}

Result<void> ReopeningMaster::start() {
    auto opened = state_->open();
    if (!opened && opened.error().kind == ErrorKind::usage) {
        return make_error(ErrorKind::usage, fmt::format("line {} ({}): {}", state_->name, link_, opened.error().message));
    }
    std::lock_guard lock(state_->mutex);
    if (opened) {
        state_->master = std::move(*opened);
        ++state_->generation;
    } else {
        state_->mark_down(opened.error().message);
    }
    return {};
}

Result<codec::Reply> ReopeningMaster::execute(std::uint8_t unit, const codec::Request& request) {
    return state_->carry([&](session::Master& line) { return line.execute(unit, request); });
}

void ReopeningMaster::execute_async(std::uint8_t unit, codec::Request request, Completion done) {
    if (concurrency_ != LinkConcurrency::one &&
        state_->send_directly(done, [&](session::Master& line, Completion sent) {
            line.execute_async(unit, std::move(request), std::move(sent));
        })) {
        return;
    }
    if (auto refused = state_->refusal()) return done(*refused);
    if (concurrency_ == LinkConcurrency::on_loop) {
        return state_->reopen_and_send(std::move(done), [unit, request](session::Master& line, Completion sent) {
            line.execute_async(unit, request, std::move(sent));
        });
    }
    state_->worker.push([state = state_.get(), unit, request = std::move(request), done = std::move(done)] {
        done(state->carry([&](session::Master& line) { return line.execute(unit, request); }));
    });
}

Result<Bytes> ReopeningMaster::forward(std::uint8_t unit, ByteView pdu) {
    return state_->carry([&](session::Master& line) { return line.forward(unit, pdu); });
}

void ReopeningMaster::forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) {
    if (concurrency_ != LinkConcurrency::one &&
        state_->send_directly(done, [&](session::Master& line, ForwardCompletion sent) {
            line.forward_async(unit, std::move(pdu), std::move(sent));
        })) {
        return;
    }
    if (auto refused = state_->refusal()) return done(*refused);
    if (concurrency_ == LinkConcurrency::on_loop) {
        return state_->reopen_and_send(std::move(done), [unit, pdu](session::Master& line, ForwardCompletion sent) {
            line.forward_async(unit, pdu, std::move(sent));
        });
    }
    state_->worker.push([state = state_.get(), unit, pdu = std::move(pdu), done = std::move(done)] {
        done(state->carry([&](session::Master& line) { return line.forward(unit, pdu); }));
    });
}

LinkHealth ReopeningMaster::health() const { return state_->health(); }

}  // namespace loopwire::gateway
