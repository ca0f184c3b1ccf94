// The master on a serial line (RTU, ASCII, Linking) or behind a serial device server (rtu+tcp).
#include <mutex>

#include "codec/rtu.hpp"
#include "session/frame_codec.hpp"
#include "session/job_queue.hpp"
#include "session/master.hpp"
#include "session/reply_check.hpp"
#include "session/transaction_text.hpp"

namespace loopwire::session {
namespace {

using Duration = Instant::duration;

class SerialMaster final : public Master {
public:
    SerialMaster(std::unique_ptr<transport::ByteStream> stream, const transport::LinkUrl& link,
                 MasterOptions options)
        : stream_(std::move(stream)),
          codec_(make_frame_codec(link, codec::Direction::reply, options.linking_ram_only)),
          options_(std::move(options)),
          clock_(options_.clock ? options_.clock : steady_clock()),
          inter_frame_gap_(gap_for(link)),
          name_(link.to_string()) {}

    Result<codec::Reply> execute(std::uint8_t unit, const codec::Request& request) override {
        auto pdu = codec::encode_request(request);
        if (!pdu) return pdu.error();
        return typed_reply(unit, request, exchange(unit, *pdu, describe_transaction(unit, request), answers_request(request)));
    }

    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override {
        jobs_.push([this, unit, request = std::move(request), done = std::move(done)] {
            done(execute(unit, request));
        });
    }

    Result<Bytes> forward(std::uint8_t unit, ByteView pdu) override {
        if (auto forwardable = check_forwardable(pdu); !forwardable) return forwardable.error();
        return exchange(unit, pdu, describe_forwarded(unit, pdu), answers_forwarded(Bytes(pdu.begin(), pdu.end())));
    }

    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override {
        jobs_.push([this, unit, pdu = std::move(pdu), done = std::move(done)] { done(forward(unit, pdu)); });
    }

    std::string describe() const override { return name_; }

private:
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
        if (options_.trace) options_.trace({clock_->now(), direction, Bytes(bytes.begin(), bytes.end()), std::move(note)});
    }

    // One request on the line, tried again after each timeout up to the retries allowed: the PDU
    // of the frame that answers it (exception replies included), empty for a broadcast.
    Result<Bytes> exchange(std::uint8_t unit, ByteView pdu, const std::string& transaction, const ReplyCheck& answers) {
        std::lock_guard lock(line_);  // one outstanding request per serial line
        TimeoutContext context{name_, options_.timeout.count(), 0, 0};
        for (unsigned attempt = 0; attempt <= options_.retries; ++attempt) {
            ++context.tries;
            auto reply = attempt_once(unit, pdu, transaction, answers, context);
            if (reply.ok() || reply.error().kind != ErrorKind::timeout) return reply;
        }
        return timeout_error(unit, transaction, context);
    }

    Result<Bytes> attempt_once(std::uint8_t unit, ByteView pdu, const std::string& transaction,
                               const ReplyCheck& answers, TimeoutContext& context) {
        auto frame = codec_->encode(unit, pdu, 0);
        if (!frame) return frame.error();
        clock_->sleep_until(line_quiet_since_ + inter_frame_gap_);
        stream_->discard_input();  // a late reply to an earlier try must not answer this one
        codec_->reset();
        trace(TraceDirection::sent, *frame, transaction);
        auto written = stream_->write(*frame);
        line_quiet_since_ = clock_->now();
        if (!written) return written.error();
        if (unit == 0) {
            // Broadcast: nobody answers; give every slave the turnaround delay to execute it.
            clock_->sleep_for(options_.turnaround);
            line_quiet_since_ = clock_->now();
            return Bytes{};
        }
        auto reply = await_reply(unit, transaction, answers, clock_->now() + options_.timeout, context);
        line_quiet_since_ = clock_->now();
        return reply;
    }

    Result<Bytes> await_reply(std::uint8_t unit, const std::string& transaction, const ReplyCheck& answers,
                              Instant deadline, TimeoutContext& context) {
        std::array<std::uint8_t, 512> buffer{};
        std::optional<Error> wrong_reply;  // the last frame from `unit` that did not answer the request
        for (;;) {
            const auto now = clock_->now();
            // A reply that came but was wrong is what went wrong, not silence: it is reported as
            // such (exit 6, as on TCP), and not retried. The wait still runs to the deadline, as
            // the right reply may follow a stale one.
            if (now >= deadline) return wrong_reply ? *wrong_reply : make_error(ErrorKind::timeout, "no reply");
            auto wait = deadline - now;
            if (auto flush_at = codec_->flush_deadline()) {
                wait = std::min<Duration>(wait, std::max<Duration>(*flush_at - now, Duration::zero()));
            }
            const auto wait_ms = std::chrono::ceil<milliseconds>(wait);
            auto got = stream_->read_some(buffer, wait_ms);
            if (!got) return got.error();
            codec::FrameEvents events;
            if (*got > 0) {
                auto fed = codec_->feed(ByteView(buffer.data(), *got), clock_->now());
                if (!fed) return fed.error();
                events = std::move(*fed);
            } else {
                events = codec_->flush(clock_->now());
            }
            for (auto& event : events) {
                if (auto answer = consider(unit, transaction, answers, event, context, wrong_reply)) return std::move(*answer);
            }
        }
    }

    // A frame that answers the request ends the wait; anything else is traced and skipped, and
    // a whole frame (check bytes right) from the asked unit that is not a valid answer is kept
    // in `wrong_reply`, with its bytes.
    std::optional<Bytes> consider(std::uint8_t unit, const std::string& transaction, const ReplyCheck& answers,
                                  const codec::FrameEvent& event, TimeoutContext& context,
                                  std::optional<Error>& wrong_reply) {
        if (const auto* discarded = std::get_if<codec::DiscardedBytes>(&event)) {
            ++context.discarded_runs;
            trace(TraceDirection::discarded, discarded->bytes, discarded->reason);
            return std::nullopt;
        }
        const auto& frame = std::get<codec::Frame>(event);
        if (frame.unit != unit) {
            trace(TraceDirection::received, frame.raw, fmt_unit_skip(frame.unit, unit));
            return std::nullopt;
        }
        if (auto answered = answers(frame.pdu); !answered) {
            trace(TraceDirection::discarded, frame.raw, answered.error().message);
            wrong_reply = wrong_reply_error(unit, transaction, answered.error(), frame.raw);
            return std::nullopt;  // a stale reply, perhaps; the right one may still come
        }
        trace(TraceDirection::received, frame.raw, reply_note(unit, frame.pdu));
        return frame.pdu;
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
    std::shared_ptr<Clock> clock_;
    Duration inter_frame_gap_;
    std::string name_;
    std::mutex line_;
    Instant line_quiet_since_{};
    JobQueue jobs_;  // last member: its thread stops before the rest is destroyed
};

}  // namespace

std::unique_ptr<Master> make_serial_master(std::unique_ptr<transport::ByteStream> stream,
                                           const transport::LinkUrl& link, MasterOptions options) {
    return std::make_unique<SerialMaster>(std::move(stream), link, std::move(options));
}

}  // namespace loopwire::session
