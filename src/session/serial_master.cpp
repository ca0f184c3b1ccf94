// The master on a serial line (RTU, ASCII, Linking) or behind a serial device server (rtu+tcp).
#include <algorithm>
#include <array>
#include <coroutine>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <functional>
#include <future>
#include <iterator>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include <fmt/format.h>

#include "codec/rtu.hpp"
#include "codec/table.hpp"
#include "common/never_sent.hpp"
#include "common/task.hpp"
#include "session/frame_codec.hpp"
#include "session/job_queue.hpp"
#include "session/line_loop.hpp"
#include "session/master.hpp"
#include "session/reply_check.hpp"
#include "session/transaction_text.hpp"

namespace loopwire::session {
namespace {

using Duration = Instant::duration;

// When replies usually start after the request, per unit and function code: the longest of the
// last few clean exchanges (a write to EEPROM takes longer than a read; a device's latency varies
// little). Zero until one is measured.
class ReplyLatency {
public:
    void record(Duration latency) {
        samples_[next_] = latency;
        next_ = (next_ + 1) % samples_.size();
    }
    Duration expected() const { return *std::max_element(samples_.begin(), samples_.end()); }

private:
    std::array<Duration, 8> samples_{};
    std::size_t next_ = 0;
};

using LatencyKey = std::pair<std::uint8_t, std::uint8_t>;  // unit, function code

// How much later than usual a reply may come and still count as on time for the duplicate rule:
// a USB adapter holds received bytes up to its latency timer (16 ms by default on FTDI chips)
// and a busy host wakes its reader late, so a reply's arrival varies by tens of milliseconds
// although the device answers on time. A real reply taken for a copy costs its request a
// failure; a copy that comes within this slack is still caught by the ambiguity rule when the
// real reply follows.
constexpr Duration reply_jitter = std::chrono::milliseconds(40);

class SerialMaster final : public Master {
public:
    SerialMaster(std::unique_ptr<transport::ByteStream> stream, const transport::LinkUrl& link,
                 MasterOptions options)
        : stream_(std::move(stream)),
          codec_(make_frame_codec(link, codec::Direction::reply, options.linking_ram_only)),
          options_(std::move(options)),
          loop_(options_.loop),
          clock_(loop_ ? loop_->clock() : options_.clock ? options_.clock : steady_clock()),
          inter_frame_gap_(gap_for(link)),
          name_(link.to_string()) {}

    // On a loop: waits until what was queued has ended, so that nothing on the loop refers to it
    // any more. What is under way is not waited out: its wait for a reply (or a silence) ends at
    // once with a link error, and nothing more is sent. A gateway told to stop, or a line being
    // reopened, would otherwise wait up to a whole timeout per line (a 20 s timeout held a
    // SIGTERM 17 s).
    ~SerialMaster() override {
        if (!loop_) return;
        if (loop_->on_loop_thread()) {
            std::fputs("loopwire: a serial master on the lines' loop was destroyed by the loop itself\n", stderr);
            std::abort();
        }
        std::promise<void> idle;
        loop_->post([this, &idle] {
            closing_ = &idle;
            closed_ = true;
            abandon_waiting();
            tell_if_idle();
        });
        idle.get_future().wait();
    }

    Result<codec::Reply> execute(std::uint8_t unit, const codec::Request& request) override {
        if (loop_) return wait_for<codec::Reply>([&](Completion done) { execute_async(unit, request, std::move(done)); });
        return run_blocking(execute_task(unit, request));
    }

    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override {
        if (loop_) {
            return enqueue<codec::Reply>(
                [this, unit, request = std::move(request)] { return execute_task(unit, request); }, std::move(done));
        }
        jobs_.push([this, unit, request = std::move(request), done = std::move(done)] {
            done(execute(unit, request));
        });
    }

    Result<Bytes> forward(std::uint8_t unit, ByteView pdu) override {
        if (loop_) {
            return wait_for<Bytes>([&](ForwardCompletion done) {
                forward_async(unit, Bytes(pdu.begin(), pdu.end()), std::move(done));
            });
        }
        return run_blocking(forward_task(unit, Bytes(pdu.begin(), pdu.end())));
    }

    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override {
        if (loop_) {
            return enqueue<Bytes>([this, unit, pdu = std::move(pdu)] { return forward_task(unit, pdu); },
                                  std::move(done));
        }
        jobs_.push([this, unit, pdu = std::move(pdu), done = std::move(done)] { done(forward(unit, pdu)); });
    }

    std::string describe() const override { return name_; }

    void close() override {
        if (!loop_) return;  // the blocking master's calls end by themselves
        loop_->post([this] {
            closed_ = true;
            abandon_waiting();
        });
    }

private:
    Task<Result<codec::Reply>> execute_task(std::uint8_t unit, codec::Request request) {
        auto pdu = codec::encode_request(request);
        if (!pdu) co_return pdu.error();
        const std::string transaction = describe_transaction(unit, request);
        const ReplyCheck answers = answers_request(request);
        auto replied = co_await exchange(unit, *pdu, transaction, answers);
        co_return typed_reply(unit, request, std::move(replied));
    }

    Task<Result<Bytes>> forward_task(std::uint8_t unit, Bytes pdu) {
        if (auto forwardable = check_forwardable(pdu); !forwardable) co_return forwardable.error();
        const std::string transaction = describe_forwarded(unit, pdu);
        const ReplyCheck answers = answers_forwarded(pdu);
        co_return co_await exchange(unit, pdu, transaction, answers);
    }

    // --- carrying exchanges on the loop (MasterOptions::loop), one at a time -------------------

    // From any thread: `make` is run on the loop, in turn, and the task it makes is carried there.
    template <typename Value, typename Make>
    void enqueue(Make make, std::function<void(Result<Value>)> done) {
        loop_->post([this, make = std::move(make), done = std::move(done)]() mutable {
            queued_.push_back([this, make = std::move(make), done = std::move(done)]() mutable {
                return deliver<Result<Value>>(make(), [this, done = std::move(done)](Result<Value> result) {
                    done(std::move(result));
                    loop_->post([this] { job_ended(); });
                });
            });
            start_next();
        });
    }

    // On the loop.
    void start_next() {
        if (current_ || queued_.empty()) return;
        auto make = std::move(queued_.front());
        queued_.pop_front();
        current_.emplace(make());
        current_->start();
    }

    // On the loop, once the job's completion has returned.
    void job_ended() {
        current_.reset();
        start_next();
        tell_if_idle();
    }

    // On the loop: lets the destructor go on once nothing is queued or carried. The last thing
    // done here: the master may be gone as soon as it is told.
    void tell_if_idle() {
        if (closing_ == nullptr || current_ || !queued_.empty()) return;
        std::exchange(closing_, nullptr)->set_value();
    }

    // On the loop, closed: the wait under way ends now (the coroutine carries on from it and
    // finds the master closed). Reading, sending and sleeping check `closed_` before waiting.
    void abandon_waiting() {
        if (!waiting_) return;
        loop_->cancel(*waiting_);
        waiting_.reset();
        std::exchange(abandon_, {})();
    }

    Error closing_error() const {
        return make_error(ErrorKind::link, name_ + ": the line is being closed (the gateway stops or reopens it); not waited for",
                          abandoned_code);
    }

    // On the loop: waits as LineLoop::wait does, and notes the wait so that closing can end it
    // at once with `abandon`.
    void wait_on_loop(int fd, Instant deadline, std::function<void()> wake, std::function<void()> abandon) {
        abandon_ = std::move(abandon);
        waiting_ = loop_->wait(fd, deadline, [this, wake = std::move(wake)] {
            waiting_.reset();
            abandon_ = {};
            wake();
        });
    }

    // A blocking call on a master that runs on the loop: queued there, waited for here.
    template <typename Value, typename Start>
    Result<Value> wait_for(Start start) {
        if (loop_->on_loop_thread()) {
            return make_error(ErrorKind::usage, name_ + ": a blocking request on the lines' loop itself would never end");
        }
        std::promise<Result<Value>> answered;
        start([&answered](Result<Value> result) { answered.set_value(std::move(result)); });
        return answered.get_future().get();
    }

    // --- waiting: blocking the thread without a loop, suspending on the loop with one -------

    // Bytes that arrive within `wait` (0: none came), as ByteStream::read_some.
    struct Reading {
        SerialMaster& master;
        std::span<std::uint8_t> buffer;
        milliseconds wait;
        Result<std::size_t> got = std::size_t{0};

        bool await_ready() {
            if (!master.loop_) {
                got = master.stream_->read_some(buffer, wait);
                return true;
            }
            if (master.closed_) {
                got = master.closing_error();
                return true;
            }
            got = master.stream_->read_some(buffer, milliseconds::zero());
            return !got || *got > 0 || wait <= milliseconds::zero();
        }
        void await_suspend(std::coroutine_handle<> resume) {
            master.read_on_loop(*this, master.clock_->now() + wait, resume);
        }
        Result<std::size_t> await_resume() { return std::move(got); }
    };

    void read_on_loop(Reading& reading, Instant deadline, std::coroutine_handle<> resume) {
        wait_on_loop(
            stream_->poll_handle(), deadline,
            [this, &reading, deadline, resume] {
                reading.got = stream_->read_some(reading.buffer, milliseconds::zero());
                // Readable but nothing for us (a wake-up that found nothing): wait on.
                if (reading.got && *reading.got == 0 && clock_->now() < deadline) {
                    return read_on_loop(reading, deadline, resume);
                }
                resume.resume();
            },
            [this, &reading, resume] {
                reading.got = closing_error();
                resume.resume();
            });
    }

    Reading read_for(std::span<std::uint8_t> buffer, milliseconds wait) { return Reading{*this, buffer, wait}; }

    struct Sleeping {
        SerialMaster& master;
        Instant until;

        bool await_ready() {
            if (!master.loop_) {
                master.clock_->sleep_until(until);
                return true;
            }
            return master.closed_ || master.clock_->now() >= until;
        }
        void await_suspend(std::coroutine_handle<> resume) {
            master.wait_on_loop(-1, until, [resume] { resume.resume(); }, [resume] { resume.resume(); });
        }
        void await_resume() {}
    };

    Sleeping sleep_until(Instant until) { return Sleeping{*this, until}; }

    // Writes a frame and returns once it has left: the stream waits for that without a loop,
    // the loop's timer with one, so that a frame's wire time holds no other line.
    Task<Result<void>> send(ByteView frame) {
        if (!loop_) co_return stream_->write(frame);
        if (closed_) co_return closing_error();
        auto left = stream_->write_without_waiting(frame);
        if (!left) co_return left.error();
        co_await sleep_until(*left);
        co_return Result<void>{};
    }

    // RTU needs 3.5 characters of silence between frames (Modbus over serial line V1.02,
    // 2.5.1.1); libmodbus does not keep it, and multi-drop lines with several slaves break on
    // that. Through a device server the server times the line. ASCII needs no gap (2.5.2.1),
    // Linking documents none; loopwire keeps the RTU gap on both: it costs little and never
    // hurts a slave.
    static Duration gap_for(const transport::LinkUrl& link) {
        if (!link.is_serial()) return Duration::zero();
        return codec::CharacterTiming{link.serial.baud, link.serial.bits_per_character()}.t3_5();
    }

    void trace(TraceDirection direction, ByteView bytes, std::string note) const {
        if (direction == TraceDirection::discarded && options_.discarded) options_.discarded->fetch_add(1, std::memory_order_relaxed);
        if (options_.trace) options_.trace({clock_->now(), direction, Bytes(bytes.begin(), bytes.end()), std::move(note)});
    }

    // One request on the line, tried again after each timeout up to the retries allowed: the PDU
    // of the frame that answers it (exception replies included), empty for a broadcast.
    // One request at a time: blocking callers queue on `line_`, the loop carries one job at a
    // time.
    Task<Result<Bytes>> exchange(std::uint8_t unit, ByteView pdu, const std::string& transaction, const ReplyCheck& answers) {
        std::unique_lock lock(line_, std::defer_lock);
        if (!loop_) lock.lock();
        if (auto unsettled = unsettled_.find(unit); unsettled != unsettled_.end()) {
            if (auto quiet = co_await wait_for_quiet_line(unsettled->second); !quiet) co_return quiet.error();
            unsettled_.erase(unit);
        }
        TimeoutContext context{name_, options_.timeout.count(), 0, 0};
        // A reply refused as the value a write replaced gets one try more than `retries`: a
        // device that answers the same bytes again was written the value it held (not_a_duplicate).
        unsigned confirmation = 0;
        for (unsigned attempt = 0; attempt <= options_.retries + confirmation; ++attempt) {
            ++context.tries;
            auto reply = co_await attempt_once(unit, pdu, transaction, answers, context, attempt > 0);
            // A try that took no reply may still get one, late: the next request must not take it.
            // (A retry of this request may: it asks the same.)
            if (!reply.ok() && is_unanswered(reply.error().kind)) unsettled_[unit] = clock_->now();
            if (reply.ok()) co_return reply;
            // A try whose reply was refused as a probable copy (not_a_duplicate) may have lost
            // its real reply, as a try that timed out has: it is tried again while tries remain.
            const bool timed_out = reply.error().kind == ErrorKind::timeout;
            const bool refused_copy = reply.error().kind == ErrorKind::mismatch && last_try_refused_a_copy_;
            if (refused_copy && last_try_refused_a_replaced_value_) confirmation = 1;
            if (!timed_out && (!refused_copy || attempt == options_.retries + confirmation)) co_return reply;
        }
        co_return timeout_error(unit, transaction, context);
    }

    static bool is_unanswered(ErrorKind kind) {
        return kind == ErrorKind::timeout || kind == ErrorKind::mismatch || kind == ErrorKind::malformed;
    }

    Duration late_reply_window() const {
        return options_.late_reply_window ? *options_.late_reply_window : options_.timeout;
    }

    // After a try that got no reply it could take, a reply to it may still arrive, late (a slow
    // device, a repeater): RTU has no transaction id to tell it from the next request's reply. So
    // before the next request to that unit everything is discarded until the line has been quiet
    // for the late-reply window since the try ended or since the unit was last heard, whichever
    // came later. Requests to other units need not wait: a late reply names its unit, which they
    // do not take (at worst it garbles their reply: no reply, not a wrong one), so a dead unit
    // costs the others no more than its timeouts. A line that never falls quiet holds the master
    // for at most four windows.
    Task<Result<void>> wait_for_quiet_line(Instant unsettled_since) {
        const Duration window = late_reply_window();
        codec_->reset();
        Instant quiet_since = unsettled_since;
        const Instant give_up = clock_->now() + 4 * window;
        std::array<std::uint8_t, 512> buffer{};
        for (;;) {
            const Instant now = clock_->now();
            const Instant quiet_enough = quiet_since + window;
            if (now >= quiet_enough || now >= give_up) break;
            auto got = co_await read_for(buffer, std::chrono::ceil<milliseconds>(std::min(quiet_enough, give_up) - now));
            if (!got) co_return got.error();
            if (*got == 0) continue;
            quiet_since = clock_->now();
            auto fed = codec_->feed(ByteView(buffer.data(), *got), quiet_since);
            if (!fed) co_return fed.error();
            discard_late(*fed);
        }
        discard_late(codec_->flush(clock_->now() + inter_frame_gap_));
        codec_->reset();
        line_quiet_since_ = std::max(line_quiet_since_, quiet_since);
        co_return Result<void>{};
    }

    // What arrived between exchanges (a late reply, a copy) is read, traced and examined before
    // it is dropped, not flushed unseen: a copy of an earlier frame marks the line as one that
    // sends copies, which the duplicate rule needs to know before the next copy races a reply.
    void hear_out_stray_input() {
        std::array<std::uint8_t, 512> buffer{};
        codec_->reset();
        for (int round = 0; round < 8; ++round) {  // bounded: a line that never stops talking
            auto got = stream_->read_some(buffer, milliseconds::zero());
            if (!got || *got == 0) break;
            auto fed = codec_->feed(ByteView(buffer.data(), *got), clock_->now());
            if (!fed) break;
            discard_late(*fed);
        }
        discard_late(codec_->flush(clock_->now() + inter_frame_gap_));
    }

    void discard_late(const codec::FrameEvents& events) {
        for (const auto& event : events) {
            if (const auto* discarded = std::get_if<codec::DiscardedBytes>(&event)) {
                trace(TraceDirection::discarded, discarded->bytes, discarded->reason);
            } else {
                const auto& frame = std::get<codec::Frame>(event);
                note_if_copy(frame);
                trace(TraceDirection::discarded, frame.raw,
                      fmt::format("late reply from unit {}, after a try that got none: not taken for the next request",
                                  frame.unit));
            }
        }
    }

    Task<Result<Bytes>> attempt_once(std::uint8_t unit, ByteView pdu, const std::string& transaction,
                                     const ReplyCheck& answers, TimeoutContext& context, bool retry) {
        last_try_refused_a_copy_ = false;  // a try that fails before it waits refused nothing
        last_try_refused_a_replaced_value_ = false;
        auto frame = codec_->encode(unit, pdu, 0);
        if (!frame) co_return frame.error();
        co_await sleep_until(line_quiet_since_ + inter_frame_gap_);
        hear_out_stray_input();
        stream_->discard_input();  // a late reply to an earlier try must not answer this one
        codec_->reset();
        trace(TraceDirection::sent, *frame, transaction);
        auto written = co_await send(*frame);
        const Instant sent_at = clock_->now();
        if (!reads_only(pdu[0])) note_write(unit, pdu, sent_at);
        line_quiet_since_ = sent_at;
        if (!written) co_return written.error();
        if (unit == 0) {
            // Broadcast: nobody answers; give every slave the turnaround delay to execute it.
            co_await sleep_until(clock_->now() + options_.turnaround);
            line_quiet_since_ = clock_->now();
            co_return Bytes{};
        }
        const Instant deadline = sent_at + options_.timeout;
        const LatencyKey key{unit, pdu[0]};
        const Duration usual = latencies_[key].expected();
        Awaited awaited{unit, pdu, transaction, answers, context, sent_at, usual, {}, {}, true, false};
        auto accepted = co_await await_reply(awaited, deadline);
        last_try_refused_a_copy_ = awaited.refused_a_copy;
        last_try_refused_a_replaced_value_ = awaited.refused_a_replaced_value;
        line_quiet_since_ = clock_->now();
        if (!accepted) co_return accepted.error();
        const Duration took = clock_->now() - sent_at;
        auto settled = co_await settle(awaited, std::move(*accepted), sent_at + usual, deadline, retry);
        if (settled && awaited.clean) latencies_[key].record(took);
        co_return settled;
    }

    // What one wait for a reply has seen so far.
    struct Awaited {
        std::uint8_t unit;
        ByteView request;
        const std::string& transaction;
        const ReplyCheck& answers;
        TimeoutContext& context;
        Instant sent_at;
        Duration usual;  // how long after the request this unit's reply usually has come; 0: unknown
        std::optional<Error> wrong_reply;  // the last frame from `unit` that did not answer the request
        codec::FrameEvents after_accepted;  // what arrived with the accepted frame, after it
        bool clean;  // nothing but the accepted frame arrived
        bool refused_a_copy;  // a frame that answered in shape was refused as a probable copy
        bool refused_a_replaced_value = false;  // ... of this read's reply from before a write over it
    };

    // Reads until a frame answers the request or the deadline passes.
    Task<Result<codec::Frame>> await_reply(Awaited& awaited, Instant deadline) {
        std::array<std::uint8_t, 512> buffer{};
        for (;;) {
            const auto now = clock_->now();
            // A reply that came but was wrong is what went wrong, not silence: it is reported as
            // such (exit 6, as on TCP), and not retried. The wait still runs to the deadline, as
            // the right reply may follow a stale one.
            if (now >= deadline) {
                co_return awaited.wrong_reply ? *awaited.wrong_reply : make_error(ErrorKind::timeout, "no reply");
            }
            auto events = co_await read_events(buffer, deadline - now);
            if (!events) co_return events.error();
            for (std::size_t i = 0; i < events->size(); ++i) {
                if (auto frame = consider(awaited, (*events)[i])) {
                    awaited.after_accepted.assign(std::make_move_iterator(events->begin() + static_cast<std::ptrdiff_t>(i + 1)),
                                                  std::make_move_iterator(events->end()));
                    co_return std::move(*frame);
                }
            }
        }
    }

    // Waits up to `limit` (or until a pending partial frame is due to be flushed) and returns the
    // frames and discarded runs that brings. Streams wait in whole milliseconds: `limit` is
    // rounded up, so a wait for a reply never ends before its deadline.
    Task<Result<codec::FrameEvents>> read_events(std::span<std::uint8_t> buffer, Duration limit) {
        const auto now = clock_->now();
        auto wait = limit;
        if (auto flush_at = codec_->flush_deadline()) {
            wait = std::min<Duration>(wait, std::max<Duration>(*flush_at - now, Duration::zero()));
        }
        co_return co_await read_events_for(buffer, std::chrono::ceil<milliseconds>(wait));
    }

    Task<Result<codec::FrameEvents>> read_events_for(std::span<std::uint8_t> buffer, milliseconds wait) {
        auto got = co_await read_for(buffer, wait);
        if (!got) co_return got.error();
        if (*got == 0) co_return codec_->flush(clock_->now());
        last_heard_ = clock_->now();
        auto fed = codec_->feed(ByteView(buffer.data(), *got), last_heard_);
        if (!fed) co_return fed.error();
        co_return std::move(*fed);
    }

    // Listens until `until` and not past it (the silence after a reply must cost no more than
    // the 3.5 characters kept anyway): whole milliseconds on the stream, then the rest slept,
    // then what has arrived meanwhile.
    Task<Result<codec::FrameEvents>> listen_until(std::span<std::uint8_t> buffer, Instant until) {
        const auto now = clock_->now();
        const auto whole = std::chrono::floor<milliseconds>(until - now);
        if (whole > milliseconds::zero()) co_return co_await read_events_for(buffer, whole);
        co_await sleep_until(until);
        co_return co_await read_events_for(buffer, milliseconds::zero());
    }

    // A frame that answers the request ends the wait; anything else is traced and skipped, and
    // a whole frame (check bytes right) from the asked unit that is not a valid answer is kept
    // in `wrong_reply`, with its bytes.
    std::optional<codec::Frame> consider(Awaited& awaited, codec::FrameEvent& event) {
        if (const auto* discarded = std::get_if<codec::DiscardedBytes>(&event)) {
            ++awaited.context.discarded_runs;
            awaited.clean = false;
            trace(TraceDirection::discarded, discarded->bytes, discarded->reason);
            return std::nullopt;
        }
        auto& frame = std::get<codec::Frame>(event);
        if (frame.unit != awaited.unit) {
            awaited.clean = false;
            note_if_copy(frame);
            heard_from(frame.unit);
            trace(TraceDirection::received, frame.raw, fmt_unit_skip(frame.unit, awaited.unit));
            return std::nullopt;
        }
        auto answered = awaited.answers(frame.pdu);
        if (answered) {
            answered = not_a_duplicate(awaited, frame.raw);
        } else {
            note_if_copy(frame);
        }
        remember(frame.raw, awaited.request);
        if (!answered) {
            awaited.clean = false;
            trace(TraceDirection::discarded, frame.raw, answered.error().message);
            awaited.wrong_reply = wrong_reply_error(awaited.unit, awaited.transaction, answered.error(), frame.raw);
            return std::nullopt;  // a stale reply, perhaps; the right one may still come
        }
        return std::move(frame);
    }

    // Duplicates. A frame with the same bytes as one that came for another request a moment ago
    // may be a copy of it (a repeater sending a frame twice), or the real reply of a register
    // that holds the same value. It is taken as the reply when it comes when this unit's replies
    // usually come; not when it comes later than that (the real reply, usually on time, has not
    // come: a copy is the likelier), nor when a damaged frame or another unit's came first in the
    // wait (that may have been the real reply, spoiled), nor at all on a line seen sending copies
    // within the last ten minutes, where a request may fail (0Bh) rather than risk another
    // request's value. The same read asked again after a write to what it reads counts as
    // another request, and a copy of its reply from before the write is never taken, even on
    // time: it would be the value the write replaced (a client's read-modify-write read back
    // the old value when the read-back's real reply came late and a repeater's copy of the first
    // read's reply on time; the soak, tests/gateway/line_soak_test.cpp, found both). A device
    // that really answers the same (a write of the value there already) is heard again on the
    // next try, whose reply is then taken.
    // Lateness alone is suspicion, not proof: a loaded host delivers a real reply late now and
    // then, so it does not mark the line as one that sends copies (a copy heard between
    // exchanges, or a second frame for one request, does), and the request is tried again
    // (exchange) while tries remain, so that a late reply equal to another register's costs
    // its request one more try, not every such request for ten minutes.
    Result<void> not_a_duplicate(Awaited& awaited, ByteView raw) {
        const auto copied = earlier_copy(raw, awaited.request, awaited.unit);
        if (!copied) return {};
        const auto now = clock_->now();
        const bool late =
            awaited.usual > Duration::zero() && now - awaited.sent_at > awaited.usual + inter_frame_gap_ + reply_jitter;
        const bool marked = line_sends_copies();
        // The same read's reply from before a write over what it reads: the value the write
        // replaced. Taken only on time, in a clean wait, from a try after one that heard these
        // bytes since the write (exchange gives it that try).
        const bool replaced = std::ranges::equal(copied->request, awaited.request);
        const bool confirmed = replaced && heard_since_write(raw, awaited.request, awaited.unit);
        if (!late && awaited.clean && !marked && (!replaced || confirmed)) return {};
        awaited.refused_a_copy = true;
        awaited.refused_a_replaced_value = replaced;
        if (marked) copy_seen_at_ = now;
        const auto ago = std::chrono::duration_cast<milliseconds>(now - copied->at).count();
        if (replaced) {
            return make_error(ErrorKind::mismatch,
                              fmt::format("the same bytes as this read's reply {} ms ago, before a write to what it reads: "
                                          "the value the write replaced, probably a copy; not taken",
                                          ago));
        }
        const char* why = late ? "and later than this unit answers"
                               : (marked ? "on a line that has sent copies" : "after a damaged or another unit's frame");
        return make_error(ErrorKind::mismatch,
                          fmt::format("the same bytes as the reply to another request {} ms ago, {}: a duplicate, "
                                      "probably; not taken",
                                      ago, why));
    }

    // The last frames from the units asked, with the request each came for.
    struct SeenFrame {
        Bytes raw;
        Bytes request;
        Instant at;
    };

    void remember(ByteView raw, ByteView request) {
        if (recent_frames_.size() == recent_frames_kept) recent_frames_.pop_front();
        recent_frames_.push_back({Bytes(raw.begin(), raw.end()), Bytes(request.begin(), request.end()), clock_->now()});
    }

    // A frame seen with the same bytes for another request, recently enough for a copy of it to
    // be still on its way; or, failing that, for `request` itself, a read (functions 1-4),
    // before a write over what it reads (then it is another request's too: the one before the
    // write). For `request` with nothing written since it would be its answer all the same, and
    // so for a write asked again: its echo is the same whatever the device held.
    std::optional<SeenFrame> earlier_copy(ByteView raw, ByteView request, std::uint8_t unit) const {
        const auto recent = clock_->now() - copy_window();
        const auto read = codec::read_span(request);
        std::optional<SeenFrame> before_write;
        for (const auto& seen : recent_frames_) {
            if (seen.at < recent || !std::ranges::equal(seen.raw, raw)) continue;
            if (!std::ranges::equal(seen.request, request)) return seen;
            if (read && !before_write && written_over(unit, *read, seen.at)) before_write = seen;
        }
        return before_write;
    }

    // Whether a try of `request` heard these bytes after the last write over what it reads.
    bool heard_since_write(ByteView raw, ByteView request, std::uint8_t unit) const {
        const auto recent = clock_->now() - copy_window();
        const auto read = codec::read_span(request);
        return std::ranges::any_of(recent_frames_, [&](const SeenFrame& seen) {
            return seen.at >= recent && std::ranges::equal(seen.raw, raw) && std::ranges::equal(seen.request, request) &&
                   read && !written_over(unit, *read, seen.at);
        });
    }

    Duration copy_window() const { return options_.timeout + late_reply_window(); }

    // Functions 1-4 read; anything else may change what a read of the unit answers.
    static bool reads_only(std::uint8_t function) { return function >= 1 && function <= 4; }

    void note_write(std::uint8_t unit, ByteView pdu, Instant sent_at) {
        auto& writes = writes_[unit];
        while (!writes.empty() && (writes.front().at < sent_at - copy_window() || writes.size() >= 64)) writes.pop_front();
        writes.push_back({sent_at, codec::written_span(pdu)});
    }

    // Whether a request that may change what `read` reads of the unit (sent to it, or
    // broadcast) went out at or after `at`: a write sent at the instant a frame was heard
    // follows it (the master sends once the line is quiet). A write elsewhere in the unit is
    // not counted (a read of other registers answers the same after it); one whose reach is not
    // known is.
    bool written_over(std::uint8_t unit, const codec::DataSpan& read, Instant at) const {
        return std::ranges::any_of(std::array<std::uint8_t, 2>{unit, std::uint8_t{0}}, [&](std::uint8_t to) {
            const auto found = writes_.find(to);
            if (found == writes_.end()) return false;
            return std::ranges::any_of(found->second, [&](const SentWrite& write) {
                return write.at >= at && (!write.span || write.span->overlaps(read));
            });
        });
    }

    bool is_copy_of_recent(ByteView raw) const {
        const auto recent = clock_->now() - (options_.timeout + late_reply_window());
        return std::ranges::any_of(recent_frames_, [&](const SeenFrame& seen) {
            return seen.at >= recent && std::ranges::equal(seen.raw, raw);
        });
    }

    // A frame that cannot be the reply awaited (another unit's, or not this request's shape) and
    // has the bytes of a recent one is a copy: the line sends copies, and from now on a reply
    // equal to another request's is not taken (not_a_duplicate). Every such sighting counts, so
    // that a copy racing a lost reply finds the line marked already: the first copy a line
    // sends, taken on time for a request of the same shape whose real reply is lost, is the
    // one case RTU leaves open (the soak, tests/gateway/line_soak_test.cpp, found it). From a unit
    // whose last request went unanswered the frame may be that request's late reply, which may
    // equal an earlier reply to it: no sign of copies.
    void note_if_copy(const codec::Frame& frame) {
        if (!unsettled_.contains(frame.unit) && is_copy_of_recent(frame.raw)) copy_seen_at_ = clock_->now();
    }

    bool line_sends_copies() const {
        return copy_seen_at_ && clock_->now() - *copy_seen_at_ < std::chrono::minutes(10);
    }

    // Ambiguity rule. RTU has no transaction id: a frame that answers the request in shape may
    // still be a duplicate of an earlier reply, or an earlier request's late reply, that came
    // before the real one. The master keeps 3.5 characters of silence after a frame before it
    // sends again anyway (Modbus over serial line V1.02, 2.5.1.1); the accepted frame is handed
    // out only once that silence has passed, and no sooner than 3.5 characters after the time
    // this unit's reply to this function usually has come (the longest of its last clean
    // exchanges, measured from the end of the request). A stray frame that arrived before the
    // real reply is thereby followed, inside that wait, by the real one; any frame (or damaged
    // frame) from the same unit starting inside it makes the reply ambiguous: it is discarded
    // as a bad reply rather than handed out as a value that may be another request's.
    //
    // What this guarantees: one stray frame that arrives after the request was sent and before
    // the real reply is never taken, as long as the real reply comes no later than this unit
    // usually answers. What it cannot: a stray frame whose real reply never comes (lost, or far
    // slower than usual) is indistinguishable from the reply unless it differs in shape (the
    // ReplyCheck) or is a copy of a recent frame (not_a_duplicate); a stray frame arriving after
    // the real reply and its silence belongs to the next exchange, where the same rules apply.
    // On a healthy line it costs nothing: the real reply comes at the usual time, so only the
    // 3.5 characters kept anyway are waited. On a retry the replies of the earlier tries answer
    // the same request, so a second frame is no ambiguity there.
    Task<Result<Bytes>> settle(Awaited& awaited, codec::Frame accepted, Instant usual_start, Instant deadline, bool retry) {
        std::optional<std::string> ambiguity;
        const Instant accepted_at = clock_->now();
        Instant quiet_until = std::max(accepted_at, usual_start) + inter_frame_gap_;
        // A reply with the same bytes as another request's recent one may be its copy, come
        // just when this reply was due, with the real reply a little behind it: the silence is
        // kept for the reply jitter too, so that the real one, if it comes, makes it ambiguous.
        // Only replies equal to a recent one pay this wait.
        if (!retry && earlier_copy(accepted.raw, awaited.request, awaited.unit)) {
            quiet_until = std::max(quiet_until, usual_start + reply_jitter + inter_frame_gap_);
        }
        // A line that keeps talking after the reply cannot settle the question: give up at the
        // deadline (or a little after the silence, if the reply came that late).
        const Instant give_up = std::max(deadline, quiet_until + inter_frame_gap_);
        const auto examine = [&](codec::FrameEvents& events) {
            for (auto& event : events) {
                if (auto other = ambiguous_with(awaited.unit, event); other && !ambiguity) ambiguity = std::move(*other);
            }
        };
        examine(awaited.after_accepted);
        std::array<std::uint8_t, 512> buffer{};
        while (!ambiguity) {
            const auto now = clock_->now();
            if (now >= quiet_until && !codec_->flush_deadline()) break;
            if (now >= give_up) {
                ambiguity = "the line did not fall silent after it";
                break;
            }
            // A partial frame pending is heard out: flushed once its own silence has passed.
            const auto flush_at = codec_->flush_deadline();
            auto events = co_await listen_until(buffer, flush_at ? std::max(quiet_until, *flush_at) : quiet_until);
            if (!events) co_return events.error();
            if (last_heard_ > accepted_at) quiet_until = std::max(quiet_until, last_heard_ + inter_frame_gap_);
            examine(*events);
        }
        line_quiet_since_ = std::max(accepted_at, last_heard_);
        if (ambiguity && !retry) {
            // The frame taken first was a copy of another request's reply, and the real one came:
            // this line sends copies.
            if (earlier_copy(accepted.raw, awaited.request, awaited.unit)) copy_seen_at_ = clock_->now();
            awaited.clean = false;
            const auto why = make_error(
                ErrorKind::mismatch,
                fmt::format("ambiguous reply: {}; a duplicate or a late reply to another request may have raced the "
                            "real one, so neither is taken",
                            *ambiguity));
            trace(TraceDirection::discarded, accepted.raw, why.message);
            co_return wrong_reply_error(awaited.unit, awaited.transaction, why, accepted.raw);
        }
        trace(TraceDirection::received, accepted.raw, reply_note(awaited.unit, accepted.pdu));
        co_return std::move(accepted.pdu);
    }

    // Whether `event`, arriving while the accepted reply settles, is another frame from `unit`
    // (whole, or damaged but starting with its address): the reason, traced, or nullopt.
    std::optional<std::string> ambiguous_with(std::uint8_t unit, const codec::FrameEvent& event) {
        if (const auto* discarded = std::get_if<codec::DiscardedBytes>(&event)) {
            trace(TraceDirection::discarded, discarded->bytes, discarded->reason);
            if (discarded->bytes.empty() || discarded->bytes[0] != unit) return std::nullopt;
            return fmt::format("a damaged frame from unit {} followed it within the silence", unit);
        }
        const auto& frame = std::get<codec::Frame>(event);
        if (frame.unit != unit) {
            heard_from(frame.unit);
            trace(TraceDirection::received, frame.raw, fmt_unit_skip(frame.unit, unit));
            return std::nullopt;
        }
        if (is_copy_of_recent(frame.raw)) copy_seen_at_ = clock_->now();
        remember(frame.raw, ByteView{});
        trace(TraceDirection::discarded, frame.raw, "a second frame from the unit for one request");
        return fmt::format("another frame from unit {} followed it within the silence", unit);
    }

    // A frame from another unit: if that unit's last request went unanswered, this may be its
    // late reply, and its window starts again.
    void heard_from(std::uint8_t other) {
        if (auto unsettled = unsettled_.find(other); unsettled != unsettled_.end()) unsettled->second = clock_->now();
    }

    static std::string reply_note(std::uint8_t unit, ByteView pdu) {
        if (pdu.size() == 2 && (pdu[0] & 0x80) != 0) return "exception " + codec::describe_exception(pdu[1]);
        return "reply from unit " + std::to_string(unit);
    }

    static std::string fmt_unit_skip(std::uint8_t got, std::uint8_t wanted) {
        return "frame from unit " + std::to_string(got) + " while waiting for unit " + std::to_string(wanted);
    }

    std::unique_ptr<transport::ByteStream> stream_;
    std::unique_ptr<FrameCodec> codec_;
    MasterOptions options_;
    std::shared_ptr<LineLoop> loop_;  // null: the blocking calls run on the caller's thread
    std::shared_ptr<Clock> clock_;
    Duration inter_frame_gap_;
    std::string name_;
    std::mutex line_;
    Instant line_quiet_since_{};
    Instant last_heard_{};   // when the last bytes arrived
    // Units whose last request got no reply it took (one may still come, late), with when the
    // try ended or the unit was last heard since.
    std::map<std::uint8_t, Instant> unsettled_;
    std::map<LatencyKey, ReplyLatency> latencies_;
    static constexpr std::size_t recent_frames_kept = 16;
    std::deque<SeenFrame> recent_frames_;
    std::optional<Instant> copy_seen_at_;  // when a copy of a frame was last seen
    // Requests that may write, by unit (0: broadcast), sent within the copy window: oldest first.
    struct SentWrite {
        Instant at;
        std::optional<codec::DataSpan> span;  // none: it may change anything
    };
    std::map<std::uint8_t, std::deque<SentWrite>> writes_;
    bool last_try_refused_a_copy_ = false;  // the last try's wait refused a frame as a probable copy
    bool last_try_refused_a_replaced_value_ = false;  // ... as a read's reply from before a write over it
    // On the loop (MasterOptions::loop): the jobs waiting, the one carried, and the destructor
    // waiting for both to end.
    std::deque<std::function<DetachedTask()>> queued_;
    std::optional<DetachedTask> current_;
    std::promise<void>* closing_ = nullptr;
    bool closed_ = false;  // close() or the destructor came: nothing more is sent or waited for
    std::optional<LineLoop::WaitId> waiting_;  // the wait under way on the loop, if any
    std::function<void()> abandon_;  // ends that wait early, when closing
    JobQueue jobs_{"lw-serial"};  // last member: its thread stops before the rest is destroyed
};

}  // namespace

std::unique_ptr<Master> make_serial_master(std::unique_ptr<transport::ByteStream> stream,
                                           const transport::LinkUrl& link, MasterOptions options) {
    return std::make_unique<SerialMaster>(std::move(stream), link, std::move(options));
}

}  // namespace loopwire::session
