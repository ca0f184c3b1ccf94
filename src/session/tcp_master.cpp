// The Modbus TCP master: transaction ids let several requests be in flight on one connection.
// Requests are written from the caller's thread; the connection is read, and replies matched
// and requests expired, on a LineLoop (session/line_loop.hpp): the gateway's lines' loop
// (MasterOptions::loop), so a Modbus TCP device costs the gateway no thread of its own, or,
// for a command-line tool, a loop of the master's own.
#include <array>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <utility>

#include <fmt/format.h>

#include "codec/tcp.hpp"
#include "common/never_sent.hpp"
#include "session/line_loop.hpp"
#include "session/master.hpp"
#include "session/reply_check.hpp"
#include "session/transaction_text.hpp"
#include "session/write_batching.hpp"
#include "transport/tcp.hpp"

namespace loopwire::session {
namespace {

struct PendingRequest {
    std::uint8_t unit = 0;
    Bytes pdu;
    std::string transaction;  // in words, for traces and errors; empty for a forwarded PDU (text())
    ReplyCheck answers;
    Instant deadline;
    unsigned tries = 1;
    bool broadcast = false;
    Master::ForwardCompletion done;  // the reply PDU (empty after a broadcast), or what failed
    std::optional<Error> wrong_reply;  // a frame with this transaction id that did not answer

    // A forwarded PDU is worded only when a trace or an error needs it: most are answered, and
    // wording each would cost the gateway's busiest path a format and two allocations.
    std::string text() const { return transaction.empty() ? describe_forwarded(unit, pdu) : transaction; }
};

class TcpMaster final : public Master {
public:
    TcpMaster(std::unique_ptr<transport::ByteStream> stream, const transport::LinkUrl& link,
              MasterOptions options)
        : link_(link),
          options_(std::move(options)),
          own_loop_(options_.loop ? nullptr : std::make_shared<LineLoop>()),
          loop_(options_.loop ? options_.loop : own_loop_),
          clock_(loop_->clock()),
          stream_(std::move(stream)) {
        std::lock_guard lock(mutex_);
        if (stream_) watch_from_anywhere();
    }

    // Posted work, the loop's wake-ups and a batch's flush find no master from here on (one
    // running now is waited for); the wait left on the loop is cancelled there.
    ~TcpMaster() override {
        std::optional<LineLoop::WaitId> watching;
        {
            std::lock_guard lock(anchor_->mutex);
            anchor_->master = nullptr;
            watching = watch_;
        }
        if (watching) {
            if (loop_->on_loop_thread()) {
                loop_->cancel(*watching);
            } else {
                loop_->post([loop = loop_.get(), id = *watching] { loop->cancel(id); });
            }
        }
        fail_all(make_error(ErrorKind::link, "master closed"));
    }

    Result<codec::Reply> execute(std::uint8_t unit, const codec::Request& request) override {
        return wait_for<codec::Reply>([&](auto done) { execute_async(unit, request, std::move(done)); });
    }

    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override {
        auto pdu = codec::encode_request(request);
        if (!pdu) return done(pdu.error());
        auto transaction = describe_transaction(unit, request);
        auto answers = answers_request(request);
        submit({unit, std::move(*pdu), std::move(transaction), std::move(answers), {}, 1, unit == 0,
                [unit, request = std::move(request), done = std::move(done)](Result<Bytes> answered) {
                    done(typed_reply(unit, request, std::move(answered)));
                },
                {}});
    }

    Result<Bytes> forward(std::uint8_t unit, ByteView pdu) override {
        return wait_for<Bytes>([&](auto done) { forward_async(unit, Bytes(pdu.begin(), pdu.end()), std::move(done)); });
    }

    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override {
        if (auto forwardable = check_forwardable(pdu); !forwardable) return done(forwardable.error());
        auto answers = answers_forwarded(pdu);
        submit({unit, std::move(pdu), {}, std::move(answers), {}, 1, unit == 0, std::move(done), {}});
    }

    std::string describe() const override { return link_.to_string(); }

    // What awaits its reply fails now, on this thread, and what comes after at once; frames
    // still waiting for the end of a loop's round are not written.
    void close() override {
        {
            std::lock_guard lock(mutex_);
            closed_ = true;
            outgoing_.clear();
            outgoing_transactions_.clear();
        }
        fail_all(closing_error());
    }

private:
    using Finished = std::pair<ForwardCompletion, Result<Bytes>>;

    Error closing_error() const {
        return make_error(ErrorKind::link, link_.to_string() + ": the line is being closed (the gateway stops or reopens it); not waited for",
                          abandoned_code);
    }

    // Blocks until the completion `start` is given has run, and returns what it was given. Not
    // on the loop's thread: the reply it waits for would be read there.
    template <typename T, typename Start>
    Result<T> wait_for(Start start) {
        if (loop_->on_loop_thread()) {
            return make_error(ErrorKind::usage, link_.to_string() + ": a blocking request on the lines' loop itself would never end");
        }
        std::promise<Result<T>> promise;
        auto future = promise.get_future();
        start([&promise](Result<T> outcome) { promise.set_value(std::move(outcome)); });
        return future.get();
    }

    void submit(PendingRequest pending) {
        std::unique_lock lock(mutex_);
        if (closed_) {
            lock.unlock();
            return pending.done(closing_error());
        }
        if (auto connected = ensure_connected(); !connected) {
            lock.unlock();
            return pending.done(connected.error());
        }
        if (auto failed = send(std::move(pending))) {
            lock.unlock();
            failed->first(std::move(failed->second));
        }
    }

    // A master on a loop of its own (a command-line tool's) connects again after the connection
    // was lost; on a gateway's loop the line's keeper reopens it (gateway/reopening_master.hpp),
    // and a blocking connect here would hold the caller's loop.
    bool reconnects() const { return own_loop_ != nullptr; }

    // Called with mutex_ held.
    Result<void> ensure_connected() {
        if (stream_ && !broken_) return {};
        if (broken_ || !reconnects()) {
            return make_error(ErrorKind::link, fmt::format("connection to {} lost: {}", link_.to_string(), lost_because_));
        }
        auto stream = transport::connect_tcp(link_.host, link_.port, options_.timeout);
        if (!stream) return stream.error();
        stream_ = std::move(*stream);
        decoder_.reset();
        watch_from_anywhere();
        return {};
    }

    // Called with mutex_ held: gives the request a new transaction id and puts it on the wire.
    // When the write fails the request is taken back, and its completion is returned with the
    // error for the caller to run once the mutex is released (the connection is dropped).
    std::optional<Finished> send(PendingRequest pending) {
        const std::uint16_t transaction = next_transaction_++;
        Bytes frame = codec::mbap_encode(transaction, pending.unit, pending.pdu);
        if (options_.trace) trace(TraceDirection::sent, frame, pending.text());
        pending.deadline = clock_->now() + (pending.broadcast ? options_.turnaround : options_.timeout);
        if (!watched_until_ || pending.deadline < *watched_until_) watch_from_anywhere();
        auto [entry, added] = pending_.insert_or_assign(transaction, std::move(pending));
        if (batched(transaction, frame)) return std::nullopt;
        auto written = stream_->write_now(frame);
        if (written) return std::nullopt;
        Finished failed{std::move(entry->second.done), written.error()};
        pending_.erase(entry);
        break_connection(written.error());
        return failed;
    }

    // Called with mutex_ held, after a write failed. The kernel did not take the frames at once:
    // the device has stopped reading (a send buffer holds thousands of requests, and no more than
    // the replies awaited are ever in it), or the connection failed. Waiting for room would hold
    // the caller (the gateway's engine, and every front with it); part of a frame may have gone.
    // So nothing more is written on it, and the loop drops it and fails what it awaits.
    void break_connection(const Error& error) {
        if (broken_) return;
        broken_ = true;
        lost_because_ = error.message;
        outgoing_.clear();
        outgoing_transactions_.clear();
        loop_->post(on_master([error, connection = connection_](TcpMaster& master) { master.drop_connection(error, connection); }));
    }

    // Called with mutex_ held. On a loop that batches writes (session/write_batching.hpp), the
    // frame joins the ones to be written at the end of the loop's round, and true is returned.
    bool batched(std::uint16_t transaction, const Bytes& frame) {
        if (!batch_flush_due_) {
            if (!WriteBatching::defer(on_master([](TcpMaster& master) { master.write_batch(); }))) return false;
            batch_flush_due_ = true;
        }
        outgoing_.insert(outgoing_.end(), frame.begin(), frame.end());
        outgoing_transactions_.push_back(transaction);
        return true;
    }

    // One write of every frame noted since the last. When it fails, its requests fail with the
    // error, as a single request's failed write does in send().
    void write_batch() {
        std::vector<Finished> failed;
        {
            std::lock_guard lock(mutex_);
            batch_flush_due_ = false;
            const Bytes frames = std::exchange(outgoing_, {});
            const auto transactions = std::exchange(outgoing_transactions_, {});
            if (frames.empty() || !stream_ || broken_) return;
            auto written = stream_->write_now(frames);
            if (written) return;
            for (const std::uint16_t transaction : transactions) {
                auto entry = pending_.find(transaction);
                if (entry == pending_.end()) continue;
                failed.emplace_back(std::move(entry->second.done), written.error());
                pending_.erase(entry);
            }
            break_connection(written.error());
        }
        for (auto& [done, result] : failed) done(std::move(result));
    }

    void trace(TraceDirection direction, ByteView bytes, std::string note) const {
        if (direction == TraceDirection::discarded && options_.discarded) options_.discarded->fetch_add(1, std::memory_order_relaxed);
        if (options_.trace) options_.trace({std::chrono::steady_clock::now(), direction, Bytes(bytes.begin(), bytes.end()), std::move(note)});
    }

    // --- on the loop ---------------------------------------------------------------------------

    // Work for the loop, a batch's flush, a wake-up: each reaches the master through the anchor,
    // which the destructor cuts (waiting for the one running).
    struct Anchor {
        explicit Anchor(TcpMaster* owner) : master(owner) {}
        std::mutex mutex;
        TcpMaster* master;
    };

    template <typename Work>
    std::function<void()> on_master(Work work) {
        return [anchor = std::weak_ptr<Anchor>(anchor_), work = std::move(work)] {
            auto held = anchor.lock();
            if (!held) return;
            std::lock_guard lock(held->mutex);
            if (held->master) work(*held->master);
        };
    }

    // Called with mutex_ held: the loop's watch on the connection is set again, on the loop,
    // for a new connection or a deadline earlier than the one it waits for. Once: a watch asked
    // for and not yet set covers whatever comes meanwhile.
    void watch_from_anywhere() {
        if (watch_asked_) return;
        watch_asked_ = true;
        loop_->post(on_master([](TcpMaster& master) { master.watch_again(); }));
    }

    void watch_again() {
        if (watch_) loop_->cancel(*watch_);
        watch_.reset();
        watch();
    }

    // The loop wakes this master when the connection has bytes (or fails) or the earliest
    // deadline of what it awaits has come. Idle, it wakes once per reply timeout anyway: a
    // request sent then expires no earlier than that, so sending it never needs the watch set
    // again (only a broadcast's shorter turnaround does).
    void watch() {
        int fd = -1;
        Instant until = Instant::max();
        {
            std::lock_guard lock(mutex_);
            watch_asked_ = false;
            if (stream_) fd = stream_->poll_handle();
            if (fd < 0 && pending_.empty()) {
                watched_until_.reset();
                return;
            }
            until = pending_.empty() ? clock_->now() + options_.timeout : earliest_deadline();
            watched_until_ = until;
        }
        watch_ = loop_->wait(fd, until, on_master([](TcpMaster& master) { master.woken(); }));
    }

    // Called with mutex_ held.
    Instant earliest_deadline() const {
        Instant earliest = Instant::max();
        for (const auto& [id, pending] : pending_) earliest = std::min(earliest, pending.deadline);
        return earliest;
    }

    void woken() {
        watch_.reset();
        transport::ByteStream* stream = nullptr;
        {
            std::lock_guard lock(mutex_);
            stream = stream_.get();
        }
        if (stream) {
            auto got = stream->read_some(buffer_, std::chrono::milliseconds(0));
            if (!got) {
                drop_connection(got.error());
            } else if (*got > 0) {
                dispatch(ByteView(buffer_.data(), *got));
            }
        }
        expire_overdue();
        if (!watch_) watch();
    }

    // `only`: the connection meant, if it may have gone (and another come) since.
    void drop_connection(const Error& error, std::optional<std::uint64_t> only = std::nullopt) {
        std::unique_ptr<transport::ByteStream> old;
        {
            std::lock_guard lock(mutex_);
            if (only && *only != connection_) return;
            ++connection_;
            old = std::move(stream_);
            broken_ = false;
            lost_because_ = error.message;
            outgoing_.clear();  // frames of the requests failed below: not for the next connection
            outgoing_transactions_.clear();
        }
        fail_all(make_error(ErrorKind::link, fmt::format("connection to {} lost: {}", link_.to_string(), error.message)));
    }

    void dispatch(ByteView bytes) {
        std::vector<Finished> finished;
        {
            std::lock_guard lock(mutex_);
            auto frames = decoder_.feed(bytes);
            if (!frames) {
                trace(TraceDirection::discarded, bytes, frames.error().message);
                decoder_.reset();
                return;
            }
            for (auto& frame : *frames) {
                if (auto done = match(frame)) finished.push_back(std::move(*done));
            }
            // The replies before a bad header were matched above; the rest of the stream is lost.
            if (const auto& broken = decoder_.broken()) {
                trace(TraceDirection::discarded, bytes, broken->message);
                decoder_.reset();
            }
        }
        for (auto& [done, result] : finished) done(std::move(result));
    }

    // Called with mutex_ held. A reply answers a request when it carries the request's
    // transaction id, names the unit asked and has the shape the request asks for (ReplyCheck:
    // function, byte count, length, echoes). A frame with an awaited id that is not such an
    // answer (a very late reply whose id came round again, a server that mixed its replies up)
    // is discarded and kept as the request's bad reply; the wait goes on to the deadline, as the
    // right reply may still come.
    std::optional<Finished> match(codec::Frame& frame) {
        auto it = pending_.find(frame.transaction);
        if (it == pending_.end() || it->second.broadcast) {
            trace(TraceDirection::discarded, frame.raw,
                  fmt::format("transaction {} is not awaited (late reply?)", frame.transaction));
            return std::nullopt;
        }
        PendingRequest& pending = it->second;
        Result<void> answers = pending.answers(frame.pdu);
        if (answers && frame.unit != pending.unit) {
            answers = make_error(ErrorKind::mismatch, fmt::format("reply names unit {}, request went to unit {}", frame.unit, pending.unit));
        }
        if (!answers) {
            trace(TraceDirection::discarded, frame.raw, answers.error().message);
            pending.wrong_reply = wrong_reply_error(pending.unit, pending.text(), answers.error(), frame.raw);
            return std::nullopt;
        }
        trace(TraceDirection::received, frame.raw, "reply");
        Finished finished{std::move(pending.done), std::move(frame.pdu)};
        pending_.erase(it);
        return finished;
    }

    void expire_overdue() {
        std::vector<Finished> finished;
        {
            std::lock_guard lock(mutex_);
            // Closing: close() fails everything pending right after it lets the mutex go; a
            // request overdue in that window is neither sent again nor told it timed out.
            if (closed_) return;
            const auto now = clock_->now();
            for (auto it = pending_.begin(); it != pending_.end();) {
                if (it->second.deadline > now) { ++it; continue; }
                PendingRequest pending = std::move(it->second);
                it = pending_.erase(it);
                if (pending.broadcast) {
                    finished.emplace_back(std::move(pending.done), Bytes{});
                } else if (pending.wrong_reply) {
                    // The server answered, wrongly: reported as such, not retried (as on serial lines).
                    finished.emplace_back(std::move(pending.done), std::move(*pending.wrong_reply));
                } else if (pending.tries <= options_.retries && stream_) {
                    ++pending.tries;
                    if (auto failed = send(std::move(pending))) finished.push_back(std::move(*failed));
                } else {
                    TimeoutContext context{link_.to_string(), options_.timeout.count(), pending.tries, 0};
                    finished.emplace_back(std::move(pending.done), timeout_error(pending.unit, pending.text(), context));
                }
            }
        }
        for (auto& [done, result] : finished) done(std::move(result));
    }

    void fail_all(const Error& error) {
        std::map<std::uint16_t, PendingRequest> failed;
        {
            std::lock_guard lock(mutex_);
            failed.swap(pending_);
        }
        for (auto& [id, pending] : failed) pending.done(error);
    }

    transport::LinkUrl link_;
    MasterOptions options_;
    std::shared_ptr<LineLoop> own_loop_;  // a command-line tool's master: its own; destroyed last
    std::shared_ptr<LineLoop> loop_;      // the one that reads the connection
    std::shared_ptr<Clock> clock_;        // the loop's: deadlines
    std::mutex mutex_;  // guards what follows, up to the loop's own
    std::unique_ptr<transport::ByteStream> stream_;
    std::string lost_because_;  // why the connection went, once it has
    bool broken_ = false;       // a write failed: nothing more goes on stream_, the loop drops it
    std::uint64_t connection_ = 0;  // which connection stream_ is (one more after each drop)
    codec::MbapDecoder decoder_;
    std::map<std::uint16_t, PendingRequest> pending_;
    std::uint16_t next_transaction_ = 1;
    bool closed_ = false;  // close(): nothing more is sent
    Bytes outgoing_;                // frames waiting for the end of the loop's round
    std::vector<std::uint16_t> outgoing_transactions_;  // theirs
    bool batch_flush_due_ = false;  // a flush of outgoing_ is deferred
    std::optional<Instant> watched_until_;  // the deadline the loop's watch wakes at; none: no watch
    bool watch_asked_ = false;              // the watch is to be set again (posted)
    // The loop's thread only (and the destructor, once the anchor is cut):
    std::optional<LineLoop::WaitId> watch_;
    std::array<std::uint8_t, 16384> buffer_{};
    std::shared_ptr<Anchor> anchor_ = std::make_shared<Anchor>(this);
};

}  // namespace

std::unique_ptr<Master> make_tcp_master(std::unique_ptr<transport::ByteStream> stream,
                                        const transport::LinkUrl& link, MasterOptions options) {
    return std::make_unique<TcpMaster>(std::move(stream), link, std::move(options));
}

}  // namespace loopwire::session
