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
#include <vector>

#include <fmt/format.h>

#include "codec/rtu.hpp"
#include "codec/table.hpp"
#include "common/never_sent.hpp"
#include "common/task.hpp"
#include "session/copy_guard.hpp"
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
    // The shortest of those measured; zero until one is.
    Duration earliest() const {
        Duration least = Duration::zero();
        for (const Duration sample : samples_) {
            if (sample != Duration::zero() && (least == Duration::zero() || sample < least)) least = sample;
        }
        return least;
    }

private:
    std::array<Duration, 8> samples_{};
    std::size_t next_ = 0;
};

using LatencyKey = std::pair<std::uint8_t, std::uint8_t>;  // unit, function code

// How much later than usual a reply may still come although the device answers on time: a USB
// adapter holds received bytes up to its latency timer (16 ms by default on FTDI chips) and a
// busy host wakes its reader late. After a frame refused as a possible copy, the real reply is
// awaited this long past when it is usually due, not the whole timeout.
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
          gap_before_sending_(std::max(inter_frame_gap_, guard_for(link))),
          name_(link.to_string()),
          copies_(copy_window()) {}

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

    // A line's guard (link_url.hpp) lengthens the silence before each frame for slaves that
    // need more than 3.5 characters to turn around; the end of a frame is still told by 3.5.
    static Duration guard_for(const transport::LinkUrl& link) {
        if (!link.is_serial()) return Duration::zero();
        return link.serial.guard_time();
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
        exchange_started_ = clock_->now();
        refused_this_exchange_.clear();
        confirmed_this_exchange_ = false;
        bool lost_a_reply = false;  // a try timed out or got a wrong reply that was no possible copy
        // A reply refused as a possible copy gets one try more than `retries`: a device that
        // answers the same bytes again, in a clean wait, said them itself (not_a_copy).
        unsigned confirmation = 0;
        for (unsigned attempt = 0; attempt <= options_.retries + confirmation; ++attempt) {
            ++context.tries;
            auto reply = co_await attempt_once(unit, pdu, transaction, answers, context, attempt > 0);
            // A try that took no reply may still get one, late: the next request must not take it.
            // (A retry of this request may: it asks the same.)
            if (!reply.ok() && is_unanswered(reply.error().kind)) {
                unsettled_[unit] = clock_->now();
                if (reply.error().kind == ErrorKind::timeout) unanswered_at_[unit] = clock_->now();
                note_fault();
            }
            if (reply.ok()) {
                // The device said again the bytes a try refused: that try had its answer, and
                // nothing of it can come late.
                if (confirmed_this_exchange_ && !lost_a_reply) unsettled_.erase(unit);
                co_return reply;
            }
            // A try whose reply was refused as a possible copy (not_a_copy) may have lost its real
            // reply, as a try that timed out has: it is tried again while tries remain.
            const bool timed_out = reply.error().kind == ErrorKind::timeout;
            const bool refused_copy = reply.error().kind == ErrorKind::mismatch && last_try_refused_a_copy_;
            if (!refused_copy) lost_a_reply = true;
            if (refused_copy) confirmation = 1;
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

    // Whatever is heard between exchanges is a fault: the line stays careful while it may echo.
    void discard_late(const codec::FrameEvents& events) {
        if (!events.empty()) note_fault();
        for (const auto& event : events) {
            if (const auto* discarded = std::get_if<codec::DiscardedBytes>(&event)) {
                copies_.heard_damaged(discarded->bytes, ByteView{}, clock_->now());
                trace(TraceDirection::discarded, discarded->bytes, discarded->reason);
            } else {
                const auto& frame = std::get<codec::Frame>(event);
                copies_.heard(frame.raw, ByteView{}, clock_->now());
                trace(TraceDirection::discarded, frame.raw,
                      fmt::format("late reply from unit {}, after a try that got none: not taken for the next request",
                                  frame.unit));
            }
        }
    }

    Task<Result<Bytes>> attempt_once(std::uint8_t unit, ByteView pdu, const std::string& transaction,
                                     const ReplyCheck& answers, TimeoutContext& context, bool retry) {
        last_try_refused_a_copy_ = false;  // a try that fails before it waits refused nothing
        auto frame = codec_->encode(unit, pdu, 0);
        if (!frame) co_return frame.error();
        co_await sleep_until(line_quiet_since_ + gap_before_sending_);
        hear_out_stray_input();
        stream_->discard_input();  // a late reply to an earlier try must not answer this one
        codec_->reset();
        trace(TraceDirection::sent, *frame, transaction);
        auto written = co_await send(*frame);
        const Instant sent_at = clock_->now();
        copies_.sent(unit, pdu, sent_at);
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
        Awaited awaited{unit, pdu, transaction, answers, context, sent_at, usual, retry, {}, {}, true, false};
        awaited.earliest = latencies_[key].earliest();
        auto accepted = co_await await_reply(awaited, deadline);
        last_try_refused_a_copy_ = awaited.refused_a_copy;
        line_quiet_since_ = clock_->now();
        if (!accepted) co_return accepted.error();
        const Duration took = clock_->now() - sent_at;
        auto settled = co_await settle(awaited, std::move(*accepted), sent_at + usual, deadline);
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
        bool retry;      // an earlier try of this request went before
        std::optional<Error> wrong_reply;  // the last frame from `unit` that did not answer the request
        codec::FrameEvents after_accepted;  // what arrived with the accepted frame, after it
        bool clean;  // nothing but the accepted frame arrived
        bool refused_a_copy;  // a frame that answered in shape was refused as a possible copy
        bool confirmed = false;  // the accepted frame has bytes an earlier try refused (not_a_copy)
        Duration earliest{};     // the soonest this unit's reply has come; 0: unknown
    };

    // Reads until a frame answers the request or the deadline passes.
    Task<Result<codec::Frame>> await_reply(Awaited& awaited, Instant deadline) {
        std::array<std::uint8_t, 512> buffer{};
        for (;;) {
            const auto now = clock_->now();
            // A reply that came but was wrong is what went wrong, not silence: it is reported as
            // such (exit 6, as on TCP), and not retried. The wait still runs to the deadline, as
            // the right reply may follow a stale one.
            const Instant until = awaited.refused_a_copy ? std::min(deadline, after_refused_copy(awaited)) : deadline;
            if (now >= until) {
                co_return awaited.wrong_reply ? *awaited.wrong_reply : make_error(ErrorKind::timeout, "no reply");
            }
            auto events = co_await read_events(buffer, until - now);
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
    // in `wrong_reply`, with its bytes. Anything but the answer is a fault of the line.
    std::optional<codec::Frame> consider(Awaited& awaited, codec::FrameEvent& event) {
        if (const auto* discarded = std::get_if<codec::DiscardedBytes>(&event)) {
            ++awaited.context.discarded_runs;
            awaited.clean = false;
            note_fault();
            copies_.heard_damaged(discarded->bytes, awaited.request, clock_->now());
            trace(TraceDirection::discarded, discarded->bytes, discarded->reason);
            return std::nullopt;
        }
        auto& frame = std::get<codec::Frame>(event);
        if (frame.unit != awaited.unit) {
            awaited.clean = false;
            note_fault();
            copies_.heard(frame.raw, ByteView{}, clock_->now());
            heard_from(frame.unit);
            trace(TraceDirection::received, frame.raw, fmt_unit_skip(frame.unit, awaited.unit));
            return std::nullopt;
        }
        auto answered = awaited.answers(frame.pdu);
        if (answered) answered = not_a_copy(awaited, frame.raw);
        copies_.heard(frame.raw, answered ? awaited.request : ByteView{}, clock_->now());
        if (!answered) {
            awaited.clean = false;
            note_fault();
            trace(TraceDirection::discarded, frame.raw, answered.error().message);
            awaited.wrong_reply = wrong_reply_error(awaited.unit, awaited.transaction, answered.error(), frame.raw);
            return std::nullopt;  // a stale reply, perhaps; the right one may still come
        }
        return std::move(frame);
    }

    // Copies. RTU has no transaction id: a frame with the same bytes as one heard within the copy
    // window for another request (a repeater or relay sending a reply again, up to hundreds of
    // milliseconds later; the late-reply window bounds how late) could be that copy, whatever
    // its delay, and a value handed out from it would be another request's. So it is refused and
    // counted, and the wait goes on a moment for the real reply (after_refused_copy). The same
    // read asked again after a write over what it reads counts as another request: a copy of its
    // reply from before the write carries the value the write replaced. Two registers that
    // really hold the same value look alike too: the request then gets one more try
    // (exchange), and bytes that the device answers again, in a wait where nothing else
    // arrived, are its own answer and taken (a copy does not come twice on cue).
    Result<void> not_a_copy(Awaited& awaited, ByteView raw) {
        const auto copied = copies_.copy_of(raw, awaited.request, awaited.unit, clock_->now(), recently_unanswered(awaited.unit));
        if (!copied) return {};
        if (awaited.retry && awaited.clean && std::ranges::find(refused_this_exchange_, Bytes(raw.begin(), raw.end())) != refused_this_exchange_.end()) {
            copies_.confirm(raw, awaited.request, exchange_started_);
            confirmed_this_exchange_ = true;
            awaited.confirmed = true;
            return {};
        }
        awaited.refused_a_copy = true;
        refused_this_exchange_.emplace_back(raw.begin(), raw.end());
        const auto ago = std::chrono::duration_cast<milliseconds>(clock_->now() - copied->at).count();
        if (copied->replaced) {
            return make_error(ErrorKind::mismatch,
                              fmt::format("the same bytes as this read's reply {} ms ago, before a write to what it reads: "
                                          "the value the write replaced, probably a copy; not taken",
                                          ago));
        }
        return make_error(ErrorKind::mismatch,
                          fmt::format("the same bytes as a frame heard {} ms ago for another request: a copy, "
                                      "possibly; not taken",
                                      ago));
    }

    // After a frame refused as a possible copy the real reply may still come, usually when this
    // unit's replies come: it is awaited until then (with the jitter a host adds), not for the
    // whole timeout, which a register that really holds another's value would cost every time.
    Instant after_refused_copy(const Awaited& awaited) const {
        if (awaited.usual == Duration::zero()) return Instant::max();
        return std::max(last_heard_ + inter_frame_gap_, awaited.sent_at + awaited.usual + inter_frame_gap_ + reply_jitter);
    }

    // How long after a frame a copy of it may come: the timeout and the late-reply window, and at
    // least a second, as a repeater's or relay's copy comes hundreds of milliseconds late whatever
    // the device's reply timeout (a line with a 100 ms timeout behind a relay copying 350 ms late
    // took another client's value for its own).
    // Whether a try to `unit` went unanswered within the copy window: then even a copy of its own
    // answer to the same request could be what arrives (a device gone silent kept "ok" by a
    // repeater's copies), and is not taken without the device saying it again.
    bool recently_unanswered(std::uint8_t unit) const {
        const auto found = unanswered_at_.find(unit);
        return found != unanswered_at_.end() && clock_->now() - found->second < copy_window();
    }

    Duration copy_window() const {
        return std::max<Duration>(options_.timeout + late_reply_window(), std::chrono::seconds(1));
    }

    // A fault (a timeout, a frame refused, damaged, from another unit or between exchanges) may
    // echo for as long as a copy can come: until then the line is careful. A frame heard damaged
    // is not remembered, so only the hold (settle) catches its copy.
    void note_fault() { careful_until_ = clock_->now() + copy_window(); }
    bool line_behaves() const { return clock_->now() >= careful_until_; }

    // A reply that is complete and checked (unit, function, byte count or echo, CRC, not a
    // possible copy) is handed out at once on a line that behaves: the next request then goes
    // out after the 3.5 characters of silence the spec asks (Modbus over serial line V1.02,
    // 2.5.1.1) and nothing more, as the copy rule and the late-reply window (exchange) already
    // keep another request's frame from being taken.
    //
    // On a line that has just shown a fault, the reply is held a little (the ambiguity rule): it
    // is handed out only once the 3.5 characters after it have passed, and no sooner than 3.5
    // characters after the time this unit's reply to this function usually comes (the longest of
    // its last clean exchanges); any frame (or damaged frame) from the same unit starting inside
    // that wait makes the reply ambiguous, and it is discarded as a bad reply rather than handed
    // out as a value that may be another request's. That catches a stray frame the copy rule
    // cannot know (a copy of a frame heard damaged) when the real reply follows it on time. On a
    // retry the replies of the earlier tries answer the same request, so a second frame is no
    // ambiguity there.
    Task<Result<Bytes>> settle(Awaited& awaited, codec::Frame accepted, Instant usual_start, Instant deadline) {
        if (line_behaves() && !awaited.confirmed) {
            line_quiet_since_ = std::max(clock_->now(), last_heard_);
            co_return hand_out(awaited, std::move(accepted));
        }
        std::optional<std::string> ambiguity;
        const Instant accepted_at = clock_->now();
        // Bytes taken as confirmed may yet be a second copy (frequent bytes, a reply many
        // clients read, are copied often), and so may bytes complete sooner than this unit has
        // ever answered (a late copy of another request's reply of the same shape, landing before
        // the real one): the real reply, if one comes, is awaited past its usual time by the host's
        // jitter, and makes them ambiguous. A host that wakes the line's reader late, or a relay
        // that paces late, can put the real reply past the usual time alone.
        const bool sooner_than_ever =
            awaited.earliest != Duration::zero() && accepted_at - awaited.sent_at + inter_frame_gap_ < awaited.earliest;
        const Instant hold_until = awaited.confirmed || sooner_than_ever ? usual_start + reply_jitter : usual_start;
        Instant quiet_until = std::max(accepted_at, hold_until) + inter_frame_gap_;
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
        if (ambiguity && (!awaited.retry || awaited.confirmed)) {
            note_fault();
            awaited.clean = false;
            const auto why = make_error(
                ErrorKind::mismatch,
                fmt::format("ambiguous reply: {}; a duplicate or a late reply to another request may have raced the "
                            "real one, so neither is taken",
                            *ambiguity));
            trace(TraceDirection::discarded, accepted.raw, why.message);
            co_return wrong_reply_error(awaited.unit, awaited.transaction, why, accepted.raw);
        }
        co_return hand_out(awaited, std::move(accepted));
    }

    Bytes hand_out(const Awaited& awaited, codec::Frame accepted) {
        copies_.answered(awaited.unit, awaited.request, accepted.raw);
        trace(TraceDirection::received, accepted.raw, reply_note(awaited.unit, accepted.pdu));
        return std::move(accepted.pdu);
    }

    // Whether `event`, arriving while the accepted reply settles, is another frame from `unit`
    // (whole, or damaged but starting with its address): the reason, traced, or nullopt.
    std::optional<std::string> ambiguous_with(std::uint8_t unit, const codec::FrameEvent& event) {
        if (const auto* discarded = std::get_if<codec::DiscardedBytes>(&event)) {
            copies_.heard_damaged(discarded->bytes, ByteView{}, clock_->now());
            trace(TraceDirection::discarded, discarded->bytes, discarded->reason);
            if (discarded->bytes.empty() || discarded->bytes[0] != unit) return std::nullopt;
            return fmt::format("a damaged frame from unit {} followed it within the silence", unit);
        }
        const auto& frame = std::get<codec::Frame>(event);
        copies_.heard(frame.raw, ByteView{}, clock_->now());
        if (frame.unit != unit) {
            heard_from(frame.unit);
            trace(TraceDirection::received, frame.raw, fmt_unit_skip(frame.unit, unit));
            return std::nullopt;
        }
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
    Duration gap_before_sending_;  // the 3.5 characters, or the line's guard where it is longer
    std::string name_;
    std::mutex line_;
    Instant line_quiet_since_{};
    Instant last_heard_{};   // when the last bytes arrived
    // Units whose last request got no reply it took (one may still come, late), with when the
    // try ended or the unit was last heard since.
    std::map<std::uint8_t, Instant> unsettled_;
    std::map<LatencyKey, ReplyLatency> latencies_;
    std::map<std::uint8_t, Instant> unanswered_at_;  // when a try to each unit last went unanswered
    CopyGuard copies_;  // frames heard and writes sent within the copy window
    Instant careful_until_{};  // until when a fault may still echo (note_fault)
    Instant exchange_started_{};
    std::vector<Bytes> refused_this_exchange_;  // frames the tries of this exchange refused as possible copies
    bool last_try_refused_a_copy_ = false;  // the last try's wait refused a frame as a possible copy
    bool confirmed_this_exchange_ = false;  // a try took bytes an earlier try refused, heard again
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
