// The Modbus TCP master: transaction ids let several requests be in flight on one connection;
// one reader thread matches replies to requests and expires the ones that time out.
#include <condition_variable>
#include <future>
#include <map>
#include <mutex>
#include <thread>

#include <fmt/format.h>

#include "codec/tcp.hpp"
#include "session/master.hpp"
#include "session/transaction_text.hpp"
#include "transport/tcp.hpp"

namespace loopwire::session {
namespace {

using Clock = std::chrono::steady_clock;

struct PendingRequest {
    std::uint8_t unit = 0;
    codec::Request request;
    Bytes pdu;
    Clock::time_point deadline;
    unsigned tries = 1;
    bool broadcast = false;
    Master::Completion done;
};

class TcpMaster final : public Master {
public:
    TcpMaster(std::unique_ptr<transport::ByteStream> stream, const transport::LinkUrl& link,
              MasterOptions options)
        : link_(link), options_(std::move(options)), stream_(std::move(stream)),
          reader_([this] { read_loop(); }) {}

    ~TcpMaster() override {
        {
            std::lock_guard lock(mutex_);
            running_ = false;
        }
        connected_.notify_all();
        reader_.join();
        fail_all(make_error(ErrorKind::link, "master closed"));
    }

    Result<codec::Reply> execute(std::uint8_t unit, const codec::Request& request) override {
        std::promise<Result<codec::Reply>> promise;
        auto future = promise.get_future();
        execute_async(unit, request, [&promise](Result<codec::Reply> r) { promise.set_value(std::move(r)); });
        return future.get();
    }

    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override {
        auto pdu = codec::encode_request(request);
        if (!pdu) return done(pdu.error());
        PendingRequest pending{unit, std::move(request), std::move(*pdu), {}, 1, unit == 0, std::move(done)};
        std::unique_lock lock(mutex_);
        if (auto connected = ensure_connected(); !connected) {
            lock.unlock();
            return pending.done(connected.error());
        }
        if (auto sent = send(std::move(pending)); !sent) {
            lock.unlock();
            fail_all(sent.error());
        }
    }

    std::string describe() const override { return link_.to_string(); }

private:
    // Called with mutex_ held.
    Result<void> ensure_connected() {
        if (stream_) return {};
        auto stream = transport::connect_tcp(link_.host, link_.port, options_.timeout);
        if (!stream) return stream.error();
        stream_ = std::move(*stream);
        decoder_.reset();
        connected_.notify_all();
        return {};
    }

    // Called with mutex_ held: gives the request a new transaction id and puts it on the wire.
    Result<void> send(PendingRequest pending) {
        const std::uint16_t transaction = next_transaction_++;
        Bytes frame = codec::mbap_encode(transaction, pending.unit, pending.pdu);
        trace(TraceDirection::sent, frame, describe_transaction(pending.unit, pending.request));
        pending.deadline = Clock::now() + (pending.broadcast ? options_.turnaround : options_.timeout);
        pending_.emplace(transaction, std::move(pending));
        auto written = stream_->write(frame);
        if (!written) pending_.erase(transaction);
        return written;
    }

    void trace(TraceDirection direction, ByteView bytes, std::string note) const {
        if (options_.trace) options_.trace({Clock::now(), direction, Bytes(bytes.begin(), bytes.end()), std::move(note)});
    }

    void read_loop() {
        std::array<std::uint8_t, 1024> buffer{};
        for (;;) {
            transport::ByteStream* stream = nullptr;
            {
                std::unique_lock lock(mutex_);
                connected_.wait_for(lock, milliseconds(50), [this] { return !running_ || stream_; });
                if (!running_) return;
                stream = stream_.get();
            }
            if (stream) {
                auto got = stream->read_some(buffer, milliseconds(20));
                if (!got) {
                    drop_connection(got.error());
                    continue;
                }
                if (*got > 0) dispatch(ByteView(buffer.data(), *got));
            }
            expire_overdue();
        }
    }

    void drop_connection(const Error& error) {
        std::unique_ptr<transport::ByteStream> old;
        {
            std::lock_guard lock(mutex_);
            old = std::move(stream_);
        }
        fail_all(make_error(ErrorKind::link, fmt::format("connection to {} lost: {}", link_.to_string(), error.message)));
    }

    void dispatch(ByteView bytes) {
        std::vector<std::pair<Completion, Result<codec::Reply>>> finished;
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

    // Called with mutex_ held.
    std::optional<std::pair<Completion, Result<codec::Reply>>> match(const codec::Frame& frame) {
        auto it = pending_.find(frame.transaction);
        if (it == pending_.end() || it->second.broadcast) {
            trace(TraceDirection::discarded, frame.raw,
                  fmt::format("transaction {} is not awaited (late reply?)", frame.transaction));
            return std::nullopt;
        }
        PendingRequest& pending = it->second;
        auto reply = codec::decode_reply(frame.pdu);
        Result<codec::Reply> outcome = reply ? codec::match_reply(pending.request, std::move(*reply)) : reply;
        if (outcome && frame.unit != pending.unit) {
            outcome = make_error(ErrorKind::mismatch, fmt::format("reply names unit {}, request went to unit {}", frame.unit, pending.unit));
        }
        if (outcome && outcome->kind == codec::ReplyKind::exception) {
            outcome = exception_error(pending.unit, pending.request, outcome->exception_code);
        }
        trace(outcome ? TraceDirection::received : TraceDirection::discarded, frame.raw,
              outcome ? std::string("reply") : outcome.error().message);
        if (!outcome && outcome.error().kind != ErrorKind::exception) {
            // Named like the serial master's: which request, why, and the bytes themselves.
            outcome = make_error(outcome.error().kind == ErrorKind::mismatch ? ErrorKind::mismatch : ErrorKind::malformed,
                                 fmt::format("unit {} answered {} with a reply that is not valid ({}): {}", pending.unit,
                                             describe_transaction(pending.unit, pending.request), outcome.error().message,
                                             to_hex(frame.raw)));
        }
        auto done = std::move(pending.done);
        pending_.erase(it);
        return std::make_pair(std::move(done), std::move(outcome));
    }

    void expire_overdue() {
        std::vector<std::pair<Completion, Result<codec::Reply>>> finished;
        {
            std::lock_guard lock(mutex_);
            const auto now = Clock::now();
            for (auto it = pending_.begin(); it != pending_.end();) {
                if (it->second.deadline > now) { ++it; continue; }
                PendingRequest pending = std::move(it->second);
                it = pending_.erase(it);
                if (pending.broadcast) {
                    finished.emplace_back(std::move(pending.done), codec::Reply{pending.request.function, codec::ReplyKind::normal, 0, pending.request.address, pending.request.count, {}});
                } else if (pending.tries <= options_.retries && stream_) {
                    ++pending.tries;
                    auto done = pending.done;
                    if (auto sent = send(std::move(pending)); !sent) finished.emplace_back(std::move(done), sent.error());
                } else {
                    TimeoutContext context{link_.to_string(), options_.timeout.count(), pending.tries, 0};
                    finished.emplace_back(std::move(pending.done), timeout_error(pending.unit, pending.request, context));
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
    std::mutex mutex_;
    std::condition_variable connected_;
    std::unique_ptr<transport::ByteStream> stream_;
    codec::MbapDecoder decoder_;
    std::map<std::uint16_t, PendingRequest> pending_;
    std::uint16_t next_transaction_ = 1;
    bool running_ = true;
    std::thread reader_;  // last: starts once everything above exists
};

}  // namespace

std::unique_ptr<Master> make_tcp_master(std::unique_ptr<transport::ByteStream> stream,
                                        const transport::LinkUrl& link, MasterOptions options) {
    return std::make_unique<TcpMaster>(std::move(stream), link, std::move(options));
}

}  // namespace loopwire::session
