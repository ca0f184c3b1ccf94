#include "gateway/line_scheduler.hpp"

#include <cassert>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <type_traits>
#include <unordered_map>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "client/monitor_backoff.hpp"
#include "common/never_sent.hpp"

namespace loopwire::gateway {
namespace {

// The back-off runs on the scheduler's injected clock, so a virtual clock drives it in tests;
// that only works while both speak of the same time points.
static_assert(std::is_same_v<Instant, device::RetryBackoff::Clock::time_point>);

void deliver(session::Master::ForwardCompletion& done, Result<Bytes> result) {
    if (done) done(std::move(result));
}

Error stopping_error() { return make_error(ErrorKind::link, "gateway stopping: the request was not sent"); }

// Marked abandoned (common/never_sent.hpp): it says nothing of the device, whose status the going
// gateway's polls must not change (to "offline" on MQTT) in the moment before they go.
Error reloading_error() {
    return make_error(ErrorKind::link, "gateway reloading its configuration: the request's outcome is not awaited; ask again",
                      abandoned_code);
}

Error expired_error(std::uint8_t unit) {
    return make_error(ErrorKind::timeout,
                      fmt::format("unit {}: the deadline passed before the line was free; not sent", unit), not_sent_code);
}

Error abandoned_error(std::uint8_t unit) {
    return make_error(ErrorKind::link, fmt::format("unit {}: the asker has gone; not sent", unit));
}

Error busy_error(std::uint8_t unit, std::size_t queued) {
    return make_error(ErrorKind::exception,
                      fmt::format("unit {}: the line has {} requests waiting, the most it queues; not queued: try again "
                                  "shortly (exception 06h, server device busy)",
                                  unit, queued),
                      server_device_busy);
}

Error backing_off_error(std::uint8_t unit, const device::RetryBackoff& backoff, Instant now) {
    const auto failures = backoff.consecutive_failures();
    const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(backoff.next_try() - now);
    return make_error(ErrorKind::timeout,
                      fmt::format("unit {} is backing off after {} consecutive timeout{}; polled again in {} ms",
                                  unit, failures, failures == 1 ? "" : "s", wait.count()));
}

// Requests of one priority from many clients: each client has its own FIFO and the clients take
// turns, so a client with a long queue delays another's request by at most the one on the wire.
class FairLane {
public:
    void push(LineRequest request) {
        auto& queue = queues_[request.client];
        if (queue.empty()) turns_.push_back(request.client);
        queue.push_back(std::move(request));
        ++size_;
    }

    std::optional<LineRequest> pop() {
        // The client served last goes to the back of the turns only now, behind every client that
        // queued while its request was on the wire. Most clients send their next request only
        // once they have the reply, so they are never queued when the line frees: put back at
        // once, a busy client would be ahead of such a one every time, taking two turns to its
        // one and making it wait for two requests, not one (with a unit that does not answer,
        // two timeouts).
        if (served_last_) turns_.push_back(*std::exchange(served_last_, std::nullopt));
        if (turns_.empty()) return std::nullopt;
        const auto client = turns_.front();
        turns_.pop_front();
        auto found = queues_.find(client);
        LineRequest request = std::move(found->second.front());
        found->second.pop_front();
        if (found->second.empty()) {
            forget_empty_queues();
        } else {
            served_last_ = client;
        }
        --size_;
        return request;
    }

    void take_all(std::vector<LineRequest>& into) {
        while (auto request = pop()) into.push_back(std::move(*request));
    }

    // Takes out every request `refuse` gives a reason for, with that reason; the others keep
    // their places and the clients their turns.
    template <typename Refuse>
    void take_refused(Refuse refuse, std::vector<std::pair<LineRequest, Error>>& into) {
        for (auto queue = queues_.begin(); queue != queues_.end();) {
            auto& requests = queue->second;
            for (auto request = requests.begin(); request != requests.end();) {
                if (auto why = refuse(*request)) {
                    into.emplace_back(std::move(*request), std::move(*why));
                    request = requests.erase(request);
                    --size_;
                } else {
                    ++request;
                }
            }
            if (!requests.empty()) {
                ++queue;
                continue;
            }
            std::erase(turns_, queue->first);
            if (served_last_ == queue->first) served_last_.reset();
            queue = queues_.erase(queue);
        }
    }

    std::size_t size() const { return size_; }

private:
    // A client's emptied queue is kept: most clients send their next request as soon as they
    // have the reply, and making the queue again each time would cost a map node and a deque's
    // blocks per request. Once more than kept_empty queues are empty, every empty one is
    // forgotten, so a storm of one-request connections leaves nothing behind.
    static constexpr std::size_t kept_empty = 64;
    void forget_empty_queues() {
        const std::size_t holding = turns_.size() + (served_last_ ? 1 : 0);  // queues not empty
        if (queues_.size() <= holding + kept_empty) return;
        std::erase_if(queues_, [](const auto& queue) { return queue.second.empty(); });
    }

    std::unordered_map<std::uint64_t, std::deque<LineRequest>> queues_;
    std::deque<std::uint64_t> turns_;  // clients with something queued, next first
    std::optional<std::uint64_t> served_last_;  // still has something queued; not in turns_ yet
    std::size_t size_ = 0;
};

// One request on the wire. A master may call the completion inside forward_async (one that
// answers at once) or later on its own thread. The first case is handed back to the loop that
// sent the request, so `done` never runs inside forward_async: not under whatever the master
// holds there, and not while the scheduler counts the master as in use (a `done` that destroys
// the scheduler would wait for itself in stop()).
struct Flight {
    std::uint8_t unit = 0;
    Priority priority = Priority::client;

    void set_done(session::Master::ForwardCompletion completion) {
        std::lock_guard lock(mutex_);
        done_ = std::move(completion);
    }
    // The asker's completion, once: empty for whoever comes second (the outcome, or a hand-over
    // that answered the asker before the outcome came).
    session::Master::ForwardCompletion take_done() {
        std::lock_guard lock(mutex_);
        return std::exchange(done_, nullptr);
    }

    // True if the completion is for the caller to handle now; false if forward_async has not
    // returned yet, in which case the result is kept for the sender.
    bool arrived(Result<Bytes>& result) {
        std::lock_guard lock(mutex_);
        if (sender_returned_) return true;
        early_.emplace(std::move(result));
        return false;
    }

    // Called by the sender once forward_async has returned: a result that came back inside it.
    std::optional<Result<Bytes>> sender_returned() {
        std::lock_guard lock(mutex_);
        sender_returned_ = true;
        return std::exchange(early_, std::nullopt);
    }

private:
    std::mutex mutex_;
    session::Master::ForwardCompletion done_;
    bool sender_returned_ = false;
    std::optional<Result<Bytes>> early_;
};

}  // namespace

struct LineScheduler::State : std::enable_shared_from_this<State> {
    State(std::shared_ptr<session::Master> line, LineSchedulerOptions chosen, std::shared_ptr<Clock> time)
        : master(std::move(line)), options(chosen), clock(std::move(time)) {
        assert(master && clock && options.max_in_flight >= 1);
    }

    void submit(LineRequest request) {
        std::optional<Error> refused;
        std::vector<std::pair<LineRequest, Error>> dropped;
        {
            std::lock_guard lock(mutex);
            if (stopping) {
                refused = stopping_error();
            } else if (handed_over) {
                refused = reloading_error();
            } else if (request.priority != Priority::poll && !make_room(dropped)) {
                ++stats.refused_busy;
                refused = busy_error(request.unit, writes.size() + clients.size());
            } else {
                enqueue(std::move(request));
            }
        }
        for (auto& [gone, why] : dropped) deliver(gone.done, std::move(why));
        if (refused) {
            deliver(request.done, std::move(*refused));
            return;
        }
        pump();
    }

    // Under the lock: whether one more write or client request fits within max_queued, once the
    // queued ones nobody waits for any more (gone, or past their deadline) are taken out into
    // `dropped`, counted as they would be when their turn came.
    bool make_room(std::vector<std::pair<LineRequest, Error>>& dropped) {
        if (writes.size() + clients.size() < options.max_queued) return true;
        const auto now = clock->now();
        auto refuse = [&](const LineRequest& queued) -> std::optional<Error> {
            if (!queued.wanted()) {
                ++stats.abandoned;
                return abandoned_error(queued.unit);
            }
            if (now >= queued.deadline) {
                ++stats.expired;
                return expired_error(queued.unit);
            }
            return std::nullopt;
        };
        writes.take_refused(refuse, dropped);
        clients.take_refused(refuse, dropped);
        return writes.size() + clients.size() < options.max_queued;
    }

    // Sends queued requests while the line is free. Runs on whichever thread found it free: the
    // submitter's, or the master's after a completion. One thread pumps at a time, so a `done`
    // that submits again only queues, and a master that answers at once makes this loop go
    // round instead of recursing as deep as the queue.
    void pump() {
        auto keep = shared_from_this();  // a `done` may destroy the scheduler while this runs
        {
            std::lock_guard lock(mutex);
            if (pumping) return;  // that thread will see what was queued
            pumping = true;
        }
        while (auto request = pop_next()) {
            auto line = admit(*request);
            if (!line) {
                deliver(request->done, line.error());
                continue;
            }
            auto flight = std::make_shared<Flight>();
            flight->unit = request->unit;
            flight->priority = request->priority;
            flight->set_done(std::move(request->done));
            {
                std::lock_guard lock(mutex);
                flights.push_back(flight);
            }
            if (auto early = send(**line, flight, std::move(request->pdu))) finish(*flight, std::move(*early));
        }
    }

    // The next request (writes, then clients and polls by turns), or nothing (and the pump
    // stops) if the line carries all it may, the scheduler is stopping or nothing is queued. Deciding that
    // and clearing `pumping` under one lock means a request queued meanwhile is never left
    // behind with nobody pumping.
    std::optional<LineRequest> pop_next() {
        std::lock_guard lock(mutex);
        std::optional<LineRequest> next;
        if (!stopping && !handed_over && in_flight < options.max_in_flight) {
            next = writes.pop();
            if (!next) next = polls_turn() ? pop_poll() : clients.pop();
        }
        if (!next) pumping = false;
        return next;
    }

    // Whether a poll goes before the clients now (header: alternate while both wait).
    bool polls_turn() const { return !polls.empty() && (clients.size() == 0 || poll_owed); }

    std::optional<LineRequest> pop_poll() {
        std::optional<LineRequest> next(std::move(polls.front()));
        polls.pop_front();
        return next;
    }

    // Whether `request` goes on the wire: if so, the line is now taken and the master to send on
    // is returned; if not, the reason (already counted).
    Result<session::Master*> admit(const LineRequest& request) {
        // Outside the lock: it is the asker's code. Checked first, since an asker that has gone
        // wants nothing, not even a timeout.
        const bool gone = !request.wanted();
        std::lock_guard lock(mutex);
        if (stopping) return stopping_error();
        if (handed_over) return reloading_error();
        if (gone) {
            ++stats.abandoned;
            return abandoned_error(request.unit);
        }
        const auto now = clock->now();
        // At the deadline itself no time is left for a reply either.
        if (now >= request.deadline) {
            ++stats.expired;
            return expired_error(request.unit);
        }
        if (auto refusal = backing_off(request, now)) {
            ++stats.backed_off;
            return *refusal;
        }
        if (in_flight++ == 0) busy_since = now;
        if (request.priority != Priority::poll) ++asked_in_flight;
        sending = true;
        ++stats.sent;
        // Turns count requests that used the line: one dropped unsent costs its kind no turn.
        if (request.priority == Priority::poll) {
            ++stats.polls_sent;
            poll_owed = false;
        } else if (request.priority == Priority::client) {
            poll_owed = true;
        }
        return master.get();
    }

    // Polls for a unit whose last poll went unanswered wait for its back-off; requests a person
    // made get a real try. Once the back-off is due the next poll is the probe. The poller asks
    // hold_poll() first, so this only catches a poll that was not asked about.
    std::optional<Error> backing_off(const LineRequest& request, Instant now) const {
        if (request.priority != Priority::poll) return std::nullopt;
        const auto found = backoffs.find(request.unit);  // only units whose last poll got no answer
        if (found == backoffs.end() || found->second.due(now)) return std::nullopt;
        return backing_off_error(request.unit, found->second, now);
    }

    std::optional<Instant> hold_poll(std::uint8_t unit) {
        std::lock_guard lock(mutex);
        const auto found = backoffs.find(unit);
        if (found == backoffs.end() || found->second.due(clock->now())) return std::nullopt;
        ++stats.backed_off;
        return found->second.next_try();
    }

    // Puts the request on the wire. Returns a result that came back inside forward_async, for the
    // caller's loop to finish.
    std::optional<Result<Bytes>> send(session::Master& line, const std::shared_ptr<Flight>& flight, Bytes pdu) {
        // The completion holds only a weak reference: it may arrive after the scheduler is gone.
        std::weak_ptr<State> weak = weak_from_this();
        line.forward_async(flight->unit, std::move(pdu), [weak, flight](Result<Bytes> result) {
            if (flight->arrived(result)) landed(weak, *flight, std::move(result));
        });
        {
            std::lock_guard lock(mutex);
            sending = false;
        }
        not_sending.notify_all();
        return flight->sender_returned();
    }

    // A completion that arrived after forward_async returned, on the master's thread.
    static void landed(const std::weak_ptr<State>& weak, Flight& flight, Result<Bytes> result) {
        auto state = weak.lock();
        if (!state) {  // the scheduler is gone; the asker still hears what the unit said
            auto done = flight.take_done();
            deliver(done, std::move(result));
            return;
        }
        state->finish(flight, std::move(result));
        state->pump();
    }

    // The line is free again: counts the result, then tells the asker.
    void finish(Flight& flight, Result<Bytes> result) {
        {
            std::lock_guard lock(mutex);
            if (--in_flight == 0) {
                stats.busy += std::chrono::duration_cast<std::chrono::microseconds>(clock->now() - busy_since);
            }
            if (flight.priority != Priority::poll) --asked_in_flight;
            std::erase_if(flights, [&flight](const std::shared_ptr<Flight>& flying) { return flying.get() == &flight; });
            record(flight, result);
        }
        auto done = flight.take_done();
        deliver(done, std::move(result));
    }

    // Every outcome is counted, but only the gateway's own polls move a unit's back-off: a
    // client's request the unit ignores (one it cannot parse, a function it does not have) costs
    // that client its 0Bh, not the unit its polls and its status.
    void record(const Flight& flight, const Result<Bytes>& result) {
        const bool poll = flight.priority == Priority::poll;
        if (result.ok()) {  // any reply, exception replies included: the unit is alive
            ++stats.answered;
            if (poll) backoffs.erase(flight.unit);
            return;
        }
        switch (result.error().kind) {
            case ErrorKind::timeout:
                ++stats.timeouts;
                if (poll) {
                    backoffs.try_emplace(flight.unit, options.first_backoff, options.max_backoff)
                        .first->second.failed(clock->now());
                }
                break;
            case ErrorKind::mismatch:
            case ErrorKind::malformed:
                // Something answered, so the unit is not silent; the back-off stays as it was.
                ++stats.bad_replies;
                break;
            case ErrorKind::link:
                // The line failed (reopening_master.hpp): the silences before may have been the
                // line's, not the units'. Every unit is polled again once it is back, at once.
                backoffs.clear();
                break;
            default:  // the request itself was refused: says nothing about the unit
                break;
        }
    }

    void enqueue(LineRequest request) {
        switch (request.priority) {
            case Priority::write: writes.push(std::move(request)); break;
            case Priority::client: clients.push(std::move(request)); break;
            case Priority::poll: polls.push_back(std::move(request)); break;
        }
    }

    // Under the lock, once no sender is inside forward_async (that call only queues, so the wait
    // is short, and afterwards the request it sent is in `flights`): every queued request.
    std::vector<LineRequest> take_queued(std::unique_lock<std::mutex>& lock) {
        not_sending.wait(lock, [this] { return !sending; });
        std::vector<LineRequest> left;
        writes.take_all(left);
        clients.take_all(left);
        for (auto& poll : polls) left.push_back(std::move(poll));
        polls.clear();
        return left;
    }

    // For the destructor: nothing is sent after this, what is queued fails, and the master is
    // released on this thread (not a completion's, see the header).
    void stop() {
        std::vector<LineRequest> left;
        std::shared_ptr<session::Master> line;
        {
            std::unique_lock lock(mutex);
            stopping = true;
            left = take_queued(lock);
            line = std::move(master);
        }
        for (auto& request : left) deliver(request.done, stopping_error());
    }

    // For a reload that keeps the line: every asker is answered now, what is queued and what is
    // on the wire alike, and nothing is taken until resume(). The requests on the wire stay there
    // until their reply or timeout: their outcome still counts (statistics, back-off) but goes to
    // no one, and the next gateway's first request waits behind it, as the line requires.
    void hand_over() {
        std::vector<LineRequest> left;
        std::vector<std::shared_ptr<Flight>> flying;
        {
            std::unique_lock lock(mutex);
            handed_over = true;
            left = take_queued(lock);  // a request being put on the wire is in `flights` afterwards
            flying = flights;
        }
        for (auto& flight : flying) {
            auto done = flight->take_done();
            deliver(done, reloading_error());
        }
        for (auto& request : left) deliver(request.done, reloading_error());
    }

    void resume() {
        {
            std::lock_guard lock(mutex);
            handed_over = false;
        }
        pump();
    }

    LineStatistics statistics() const {
        std::lock_guard lock(mutex);
        auto copy = stats;
        copy.queued = writes.size() + clients.size() + polls.size();
        copy.on_wire = in_flight > 0;
        copy.asked = writes.size() + clients.size() + asked_in_flight;
        copy.in_flight = in_flight;
        copy.open = std::chrono::duration_cast<std::chrono::microseconds>(clock->now() - opened);
        return copy;
    }

    mutable std::mutex mutex;
    std::condition_variable not_sending;
    std::shared_ptr<session::Master> master;  // null once stopped
    const LineSchedulerOptions options;
    const std::shared_ptr<Clock> clock;

    FairLane writes;
    FairLane clients;
    std::deque<LineRequest> polls;  // FIFO: polls are all the gateway's own, no one to be fair to
    std::vector<std::shared_ptr<Flight>> flights;  // on the wire now
    std::map<std::uint8_t, device::RetryBackoff> backoffs;  // units whose last poll timed out
    LineStatistics stats;
    const Instant opened = clock->now();
    Instant busy_since{};  // since in_flight last went from 0 to 1

    std::size_t in_flight = 0;  // requests on the wire
    std::size_t asked_in_flight = 0;  // of which clients' requests and writes
    bool pumping = false;    // a thread is in pump()
    bool sending = false;    // a thread is inside master->forward_async
    bool stopping = false;
    bool handed_over = false;  // between hand_over() and resume(): every request refused
    bool poll_owed = false;  // a client's request went last: a waiting poll goes next
};

LineScheduler::LineScheduler(std::shared_ptr<session::Master> master, LineSchedulerOptions options,
                             std::shared_ptr<Clock> clock)
    : state_(std::make_shared<State>(std::move(master), options, std::move(clock))) {}

LineScheduler::~LineScheduler() { state_->stop(); }

void LineScheduler::submit(LineRequest request) { state_->submit(std::move(request)); }

LineStatistics LineScheduler::statistics() const { return state_->statistics(); }

std::optional<Instant> LineScheduler::hold_poll(std::uint8_t unit) { return state_->hold_poll(unit); }

void LineScheduler::hand_over() { state_->hand_over(); }

void LineScheduler::resume() { state_->resume(); }

}  // namespace loopwire::gateway
