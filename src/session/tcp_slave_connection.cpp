#include "session/tcp_slave_connection.hpp"

#include <atomic>
#include <utility>

#include <boost/asio/post.hpp>
#include <boost/asio/write.hpp>
#include <fmt/format.h>

#include "codec/tcp.hpp"

namespace loopwire::session::detail {
namespace {

namespace asio = boost::asio;
using Clock = std::chrono::steady_clock;
using boost::system::error_code;

// How long a connection that is being closed (after a bad MBAP header, or the client's end of
// stream) may take to hand over the replies still owed before it is closed regardless.
constexpr std::chrono::seconds closing_grace{2};

// Origins name connections to the handlers for as long as the process runs: numbered, not
// addresses, which a later connection could reuse.
std::atomic<UnitHandler::Origin> connections_made{0};

}  // namespace

namespace {
thread_local const ReplyMailbox* mailbox_running_here = nullptr;
}  // namespace

bool ReplyMailbox::on_loop_thread() const { return mailbox_running_here == this; }

ReplyMailbox::RunningHere::RunningHere(const ReplyMailbox& mailbox) : before_(std::exchange(mailbox_running_here, &mailbox)) {}

ReplyMailbox::RunningHere::~RunningHere() { mailbox_running_here = before_; }

void ReplyMailbox::post(std::function<void()> work) {
    std::lock_guard lock(mutex_);
    if (loop_ == nullptr) return;
    delivered_.push_back(std::move(work));
    if (delivered_.size() == 1) asio::post(*loop_, [self = shared_from_this()] { self->run_delivered(); });
}

void ReplyMailbox::run_delivered() {
    std::vector<std::function<void()>> batch;
    {
        std::lock_guard lock(mutex_);
        batch.swap(delivered_);
    }
    for (auto& work : batch) work();
}

void ReplyMailbox::close() {
    std::lock_guard lock(mutex_);
    loop_ = nullptr;
    delivered_.clear();
}

// Whether the client at the socket's address is in the slave's write_allow, decided once at
// accept: every request of the connection carries it to the units.
bool TcpSlaveConnection::may_write(const Slave& slave, const asio::ip::tcp::socket& socket) {
    if (slave.options().access.write_allow.empty()) return true;
    error_code error;
    const auto endpoint = socket.remote_endpoint(error);
    return !error && slave.options().access.write_allow.allows(endpoint.address());
}

namespace {

// The client's address and port as the log and the audit name it.
std::string peer_of(const asio::ip::tcp::socket& socket) {
    error_code error;
    const auto endpoint = socket.remote_endpoint(error);
    return error ? std::string("a client that has gone") : fmt::format("{}:{}", endpoint.address().to_string(), endpoint.port());
}

}  // namespace

TcpSlaveConnection::TcpSlaveConnection(Slave& slave, ConnectionOwner& owner, std::shared_ptr<ReplyMailbox> mailbox,
                                       asio::ip::tcp::socket socket)
    : slave_(slave),
      owner_(owner),
      mailbox_(std::move(mailbox)),
      socket_(std::move(socket)),
      timer_(socket_.get_executor()),
      codec_(make_frame_codec(slave.link(), codec::Direction::request)),
      mbap_(slave.link().framing == transport::Framing::tcp),
      asker_(++connections_made, wanted_, may_write(slave, socket_), std::make_shared<const std::string>(peer_of(socket_))),
      peer_(*asker_.peer) {}

// Requests keep being read while replies queue up: a client that does not read its replies
// is closed at the bound instead (queue()). Pausing reads for it would only keep its memory and
// its descriptor busy forever. Reads pause for deferred requests, which only the handlers bound.
bool TcpSlaveConnection::may_read() const {
    return !closed_ && !closing_ && waiting_.empty() && outstanding_ < slave_.options().tcp.max_outstanding_requests;
}

void TcpSlaveConnection::start() {
    // A synchronous send returns would_block instead of waiting (flush_output()); the
    // asynchronous calls are unaffected.
    error_code ignored;
    socket_.non_blocking(true, ignored);
    read();
}

void TcpSlaveConnection::read() {
    reading_ = true;
    socket_.async_read_some(asio::buffer(input_), [self = shared_from_this()](const error_code& error, std::size_t size) {
        self->on_read(error, size);
    });
}

void TcpSlaveConnection::on_read(const error_code& error, std::size_t size) {
    reading_ = false;
    take(error, size);
    after_turn();
}

// One read's worth of bytes (or its failure): every complete frame is answered and the replies
// go out in one write.
void TcpSlaveConnection::take(const error_code& error, std::size_t size) {
    if (closed_ || closing_) return;
    if (error == asio::error::eof) {  // the client is done sending: a normal end, not traced
        // Modbus clients end a connection with close(), which looks the same as shutdown(): the
        // replies already on their way are still sent, but nothing more is put on a line for it
        // (what a connect-send-close flood would otherwise queue there).
        ended_by_client_ = true;
        stop_wanting();
        if (slave_.tracing() && (outstanding_ > 0 || !waiting_.empty())) {
            slave_.trace(TraceDirection::discarded, {},
                         fmt::format("the client ended the connection: its {} request(s) in progress are no longer wanted",
                                     outstanding_ + waiting_.size()));
        }
        close_after_replies({});
        return;
    }
    if (error) {
        close();
        return;
    }
    last_active_ = Clock::now();
    auto events = codec_->feed(ByteView(input_.data(), size), last_active_);
    if (!events) {
        if (slave_.tracing()) slave_.trace(TraceDirection::discarded, ByteView(input_.data(), size), events.error().message + "; connection closed");
        close();
        return;
    }
    batching_ = true;
    handle(*events);
    batching_ = false;
    if (closed_) return;
    // Modbus Messaging on TCP/IP V1.0b, 4.2: the frames before a bad header were complete
    // requests and are answered; the stream cannot be followed past it.
    if (auto broken = codec_->stream_error()) {
        close_after_replies(broken->message);
        return;
    }
    arm_timer();
    flush_output();
}

void TcpSlaveConnection::handle(codec::FrameEvents& events) {
    const std::size_t limit = slave_.options().tcp.max_outstanding_requests;
    for (auto& event : events) {
        if (closed_) return;
        if (auto* frame = std::get_if<codec::Frame>(&event)) {
            served_any_ = true;
            // In order: once one waits, every later one waits behind it.
            if (waiting_.empty() && outstanding_ < limit) {
                dispatch(std::move(*frame));
            } else {
                waiting_.push_back(std::move(*frame));
            }
        } else if (slave_.tracing()) {
            const auto& discarded = std::get<codec::DiscardedBytes>(event);
            slave_.trace(TraceDirection::discarded, discarded.bytes, discarded.reason);
        }
    }
}

// The reply may come at once (on this thread, inside answer_async) or later from any thread:
// then it is posted into the loop, and dropped if the connection has gone in the meantime.
void TcpSlaveConnection::dispatch(codec::Frame frame) {
    ++outstanding_;
    const std::uint8_t unit = frame.unit;
    const std::uint16_t transaction = frame.transaction;
    slave_.answer_async(std::move(frame), asker_, [weak = weak_from_this(), mailbox = mailbox_, unit,
                                transaction](std::optional<Bytes> pdu) mutable {
        if (mailbox->on_loop_thread()) {
            if (auto self = weak.lock()) self->deliver(unit, transaction, std::move(pdu));
            return;
        }
        mailbox->post([weak = std::move(weak), unit, transaction, pdu = std::move(pdu)]() mutable {
            if (auto self = weak.lock()) self->deliver(unit, transaction, std::move(pdu));
        });
    });
}

// Requests that waited for the outstanding ones to come down, passed on while there is room
// (called with batching_ set: replies that come at once go out together afterwards).
void TcpSlaveConnection::dispatch_waiting() {
    const std::size_t limit = slave_.options().tcp.max_outstanding_requests;
    while (!closed_ && !waiting_.empty() && outstanding_ < limit) {
        codec::Frame frame = std::move(waiting_.front());
        waiting_.pop_front();
        dispatch(std::move(frame));
    }
}

void TcpSlaveConnection::stop_wanting() { wanted_->store(false); }

void TcpSlaveConnection::deliver(std::uint8_t unit, std::uint16_t transaction, std::optional<Bytes> pdu) {
    --outstanding_;
    if (closed_) return;
    last_active_ = Clock::now();
    if (pdu) queue(unit, transaction, *pdu);
    if (!batching_) after_turn();
}

void TcpSlaveConnection::queue(std::uint8_t unit, std::uint16_t transaction, const Bytes& pdu) {
    const std::size_t start = queued_.size();
    if (mbap_) {
        codec::mbap_append(queued_, transaction, unit, pdu);  // no allocation once the queue has grown
    } else {
        auto adu = codec_->encode(unit, pdu, transaction);
        if (!adu) {
            if (slave_.tracing()) slave_.trace(TraceDirection::discarded, pdu, "reply not sent: " + adu.error().message);
            return;
        }
        queued_.insert(queued_.end(), adu->begin(), adu->end());
    }
    if (slave_.tracing()) slave_.trace(TraceDirection::sent, ByteView(queued_).subspan(start), "reply");
    const std::size_t limit = slave_.options().tcp.max_queued_reply_bytes;
    if (queued_bytes() > limit) {
        if (slave_.tracing()) {
            slave_.trace(TraceDirection::discarded, {},
                         fmt::format("the client does not read its replies: {} bytes queued (limit {}); connection closed",
                                     queued_bytes(), limit));
        }
        close();
    }
}

// Everything queued goes out in one send, straight away: the kernel nearly always takes it all,
// and then no completion has to run. What it does not take is written asynchronously.
void TcpSlaveConnection::flush_output() {
    if (closed_ || write_active_ || queued_.empty()) return;
    error_code error;
    const std::size_t sent = socket_.write_some(asio::buffer(queued_), error);
    if (error && error != asio::error::would_block) {
        close();
        return;
    }
    queued_.erase(queued_.begin(), queued_.begin() + static_cast<std::ptrdiff_t>(sent));
    if (!queued_.empty()) write();
}

// The rest of the queue, asynchronously; what is queued meanwhile waits for the next write.
void TcpSlaveConnection::write() {
    writing_.swap(queued_);
    write_active_ = true;
    asio::async_write(socket_, asio::buffer(writing_), [self = shared_from_this()](const error_code& error, std::size_t) {
        self->on_written(error);
    });
}

void TcpSlaveConnection::on_written(const error_code& error) {
    write_active_ = false;
    writing_.clear();  // keeps its capacity for the next swap
    if (closed_) return;
    if (error) {
        close();
        return;
    }
    after_turn();
}

// What a connection does when a read, a write, a timer or a deferred reply has been handled.
void TcpSlaveConnection::after_turn() {
    if (!closed_ && !waiting_.empty()) {
        batching_ = true;
        dispatch_waiting();
        batching_ = false;
    }
    flush_output();
    if (closed_) return;
    if (closing_) {
        if (write_active_ || outstanding_ > 0 || !waiting_.empty()) return;
        // FIN after the last reply, so the client reads the replies before it sees the end.
        error_code ignored;
        socket_.shutdown(asio::ip::tcp::socket::shutdown_send, ignored);
        close();
        return;
    }
    if (!reading_ && may_read()) read();
}

// RTU frames through a device server: a frame whose function code gives no length ends by
// silence (Modbus over serial line V1.02, 2.5.1.1), so the codec is flushed at its deadline.
void TcpSlaveConnection::arm_timer() {
    if (closing_) return;
    const auto deadline = codec_->flush_deadline();
    if (!deadline) return;
    timer_.expires_at(*deadline);
    timer_.async_wait([self = shared_from_this()](const error_code& error) { self->on_timer(error); });
}

void TcpSlaveConnection::on_timer(const error_code& error) {
    if (error || closed_) return;  // re-armed, or closed
    if (closing_) {
        close();  // the grace period is over
        return;
    }
    // A wait that had already expired when the timer was re-armed still runs: check the time.
    const auto deadline = codec_->flush_deadline();
    if (!deadline) return;
    if (*deadline > Clock::now()) {
        arm_timer();
        return;
    }
    auto events = codec_->flush(Clock::now());
    batching_ = true;
    handle(events);
    batching_ = false;
    if (closed_) return;
    arm_timer();
    after_turn();
}

void TcpSlaveConnection::close_after_replies(const std::string& reason) {
    if (closing_ || closed_) return;
    if (!reason.empty() && slave_.tracing()) {
        slave_.trace(TraceDirection::discarded, {}, reason + "; closing once the replies owed are sent");
    }
    closing_ = true;
    timer_.expires_after(closing_grace);
    timer_.async_wait([self = shared_from_this()](const error_code& error) { self->on_timer(error); });
    after_turn();
}

void TcpSlaveConnection::close() {
    if (closed_) return;
    closed_ = true;
    stop_wanting();
    waiting_.clear();
    error_code ignored;
    socket_.close(ignored);
    timer_.cancel();
    owner_.forget(this);  // the caller's handler still holds a reference: `this` lives on
}

}  // namespace loopwire::session::detail
