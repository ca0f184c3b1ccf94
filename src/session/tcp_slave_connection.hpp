#pragma once
// One accepted TCP client of a slave (internal to session/, used by tcp_slave_server.cpp).
//
// Reads go into one fixed buffer and through the connection's own FrameCodec (MBAP, or RTU for
// rtu+tcp with its silence flush on a timer); every complete frame is answered, and replies are
// appended to one queue that goes out in a single send per read. A client that
// stops reading is closed once its queue passes TcpClientLimits::max_queued_reply_bytes; one
// that pipelines past TcpClientLimits::max_outstanding_requests is not read until it is below.
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>

#include "session/frame_codec.hpp"
#include "session/slave.hpp"

namespace loopwire::session::detail {

// What a connection needs from the server that owns it (called on the loop thread only).
class ConnectionOwner {
public:
    virtual ~ConnectionOwner() = default;
    // The connection has closed: the server drops its reference.
    virtual void forget(const void* connection) = 0;
};

// Where deferred replies enter the loop. A unit handler may answer from any thread, and even
// after the server has stopped: the mailbox outlives the loop (shared by every pending reply)
// and drops what arrives once close() has run. Replies that come while the loop has not yet
// taken the earlier ones ride along with them: one post, and one wake of the loop, per batch.
class ReplyMailbox : public std::enable_shared_from_this<ReplyMailbox> {
public:
    explicit ReplyMailbox(boost::asio::io_context& loop) : loop_(&loop) {}
    // True on the thread running the loop (inside a RunningHere): the reply can be handled at
    // once. Asked for every request: a thread-local mark, no lock.
    bool on_loop_thread() const;
    // Marks the calling thread as the loop's for as long as it exists: the server's serve(),
    // around the loop's run().
    class RunningHere {
    public:
        explicit RunningHere(const ReplyMailbox& mailbox);
        ~RunningHere();
        RunningHere(const RunningHere&) = delete;
        RunningHere& operator=(const RunningHere&) = delete;

    private:
        const ReplyMailbox* before_;
    };
    // Runs `work` on the loop later, or never if the server has stopped.
    void post(std::function<void()> work);
    // The loop is going away (called on the loop's thread).
    void close();

private:
    void run_delivered();

    mutable std::mutex mutex_;
    boost::asio::io_context* loop_;  // guarded by mutex_; null once closed
    std::vector<std::function<void()>> delivered_;  // guarded by mutex_; a run is posted while not empty
};

class TcpSlaveConnection : public std::enable_shared_from_this<TcpSlaveConnection> {
public:
    TcpSlaveConnection(Slave& slave, ConnectionOwner& owner, std::shared_ptr<ReplyMailbox> mailbox,
                       boost::asio::ip::tcp::socket socket);
    TcpSlaveConnection(const TcpSlaveConnection&) = delete;
    TcpSlaveConnection& operator=(const TcpSlaveConnection&) = delete;

    void start();
    void close();
    // Stops reading, sends the replies still owed, then closes; `reason` is traced unless empty.
    void close_after_replies(const std::string& reason);

    // For the server's limits (TcpClientLimits::max_connections, idle_timeout), on the loop.
    // Idle: no request in progress, none waiting to be passed on.
    bool idle() const { return outstanding_ == 0 && waiting_.empty(); }
    // The client has ended its side: it wants nothing more.
    bool ended_by_client() const { return ended_by_client_; }
    // Whether a whole request ever came.
    bool served_any() const { return served_any_; }
    // When a byte last came in or a reply was last handed over (the accept, before either).
    std::chrono::steady_clock::time_point last_active() const { return last_active_; }
    // "127.0.0.1:40312", for the log.
    const std::string& peer() const { return peer_; }

private:
    static bool may_write(const Slave& slave, const boost::asio::ip::tcp::socket& socket);
    void read();
    void on_read(const boost::system::error_code& error, std::size_t size);
    void take(const boost::system::error_code& error, std::size_t size);
    void flush_output();
    void handle(codec::FrameEvents& events);
    void dispatch(codec::Frame frame);
    void dispatch_waiting();
    void stop_wanting();
    void deliver(std::uint8_t unit, std::uint16_t transaction, std::optional<Bytes> pdu);
    void queue(std::uint8_t unit, std::uint16_t transaction, const Bytes& pdu);
    void write();
    void on_written(const boost::system::error_code& error);
    void arm_timer();
    void on_timer(const boost::system::error_code& error);
    void after_turn();
    bool may_read() const;
    std::size_t queued_bytes() const { return queued_.size() + writing_.size(); }

    Slave& slave_;
    ConnectionOwner& owner_;
    std::shared_ptr<ReplyMailbox> mailbox_;
    boost::asio::ip::tcp::socket socket_;
    boost::asio::steady_timer timer_;  // RTU silence flush; the last grace period when closing
    std::unique_ptr<FrameCodec> codec_;
    const bool mbap_;
    // This connection, as the handlers see it; its flag goes false when the client has gone or
    // ended its side, and requests of it still queued for a line are dropped (UnitHandler::Asker).
    std::shared_ptr<std::atomic<bool>> wanted_ = std::make_shared<std::atomic<bool>>(true);
    const UnitHandler::Asker asker_;
    std::string peer_;
    std::array<std::uint8_t, 4096> input_{};
    Bytes queued_;   // replies waiting for the write in progress to finish
    Bytes writing_;  // the write in progress
    std::size_t outstanding_ = 0;  // requests whose reply has not been delivered yet
    // Whole requests read while max_outstanding_requests were outstanding: passed on in order as
    // replies come. At most one read's worth, since the socket is not read while any wait.
    std::deque<codec::Frame> waiting_;
    std::chrono::steady_clock::time_point last_active_ = std::chrono::steady_clock::now();
    bool served_any_ = false;
    bool ended_by_client_ = false;
    bool reading_ = false;
    bool write_active_ = false;
    bool batching_ = false;  // answering a read: replies gather and go out in one send afterwards
    bool closing_ = false;   // answer what has been received, then close
    bool closed_ = false;
};

}  // namespace loopwire::session::detail
