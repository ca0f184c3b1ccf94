#include "session/tcp_slave_server.hpp"

#include <fcntl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <memory>
#include <unordered_map>
#include <vector>

#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <fmt/format.h>

#include "session/slave.hpp"
#include "session/tcp_slave_connection.hpp"
#include "session/write_batching.hpp"

namespace loopwire::session {
namespace {

namespace asio = boost::asio;
using asio::ip::tcp;
using boost::system::error_code;

// accept() failures that concern only the client being accepted (it gave up, or a firewall
// refused it): the next one can be accepted at once. Every other failure -- EMFILE, ENFILE,
// ENOBUFS, ENOMEM, or something unforeseen -- would fail again just as fast while the client
// waits in the backlog, so accepting pauses instead of spinning.
bool concerns_one_client(const error_code& error) {
    return error == asio::error::connection_aborted || error == asio::error::interrupted ||
           error == asio::error::would_block || error.value() == EPROTO || error.value() == EPERM;
}

class TcpSlaveServer final : public detail::ConnectionOwner {
public:
    TcpSlaveServer(Slave& slave, asio::io_context* shared)
        : slave_(slave), own_loop_(shared ? nullptr : std::make_unique<asio::io_context>(1)), loop_(shared ? *shared : *own_loop_) {}
    TcpSlaveServer(const TcpSlaveServer&) = delete;
    TcpSlaveServer& operator=(const TcpSlaveServer&) = delete;
    ~TcpSlaveServer() override { shut_down(); }

    Result<void> serve(transport::TcpListener& listener, std::stop_token stop);
    void forget(const void* connection) override {
        connections_.erase(connection);
        slave_.count(Slave::ConnectionEvent::closed);
        if (stopping_ && connections_.empty()) loop_.stop();
    }

private:
    using Connection = std::shared_ptr<detail::TcpSlaveConnection>;

    Result<void> adopt(const transport::TcpListener& listener);
    void accept();
    void on_accept(const error_code& error, tcp::socket socket);
    bool allowed(tcp::socket& newcomer);
    bool make_room(tcp::socket& newcomer);
    Connection eviction_candidate() const;
    void log(const std::string& line) const;
    void watch_idle();
    void close_idle();
    void stop_gracefully();
    void shut_down();

    Slave& slave_;
    // Declared first, destroyed last: pending handlers (and the connections they hold) go with
    // it. On a caller's loop they go with that loop, which outlives the server.
    std::unique_ptr<asio::io_context> own_loop_;
    asio::io_context& loop_;
    tcp::acceptor acceptor_{loop_};
    asio::steady_timer accept_pause_{loop_};
    asio::steady_timer stop_limit_{loop_};
    asio::steady_timer idle_check_{loop_};  // armed while connections are open and idle_timeout is set
    bool idle_check_armed_ = false;
    bool stopping_ = false;
    std::shared_ptr<detail::ReplyMailbox> mailbox_ = std::make_shared<detail::ReplyMailbox>(loop_);
    std::unordered_map<const void*, Connection> connections_;
};

// The acceptor works on its own duplicate of the listener's socket, so the listener keeps its
// descriptor (and its port) when serving ends.
Result<void> TcpSlaveServer::adopt(const transport::TcpListener& listener) {
    const int fd = ::fcntl(listener.poll_handle(), F_DUPFD_CLOEXEC, 0);
    if (fd < 0) {
        return make_error(ErrorKind::link, "cannot serve port " + std::to_string(listener.port()) + ": " +
                                               std::system_category().message(errno));
    }
    sockaddr_storage address{};
    socklen_t length = sizeof address;
    const bool ipv6 = ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) == 0 && address.ss_family == AF_INET6;
    error_code error;
    acceptor_.assign(ipv6 ? tcp::v6() : tcp::v4(), fd, error);
    if (error) {
        ::close(fd);
        return make_error(ErrorKind::link, "cannot serve port " + std::to_string(listener.port()) + ": " + error.message());
    }
    return {};
}

Result<void> TcpSlaveServer::serve(transport::TcpListener& listener, std::stop_token stop) {
    if (auto adopted = adopt(listener); !adopted) return adopted.error();
    accept();
    {
        // The callback may run on the stopping thread, or here at once if stop was requested
        // already; post() is thread-safe and the loop runs the graceful stop on its own thread.
        std::stop_callback on_stop(stop, [this] { asio::post(loop_, [this] { stop_gracefully(); }); });
        // Requests forwarded to a pipelined TCP line while handling this round's clients go out
        // in one write at its end (session/write_batching.hpp).
        WriteBatching::Scope batching([this](std::function<void()> work) { asio::post(loop_, std::move(work)); });
        detail::ReplyMailbox::RunningHere here(*mailbox_);
        loop_.run();
    }
    shut_down();
    return {};
}

void TcpSlaveServer::accept() {
    acceptor_.async_accept([this](const error_code& error, tcp::socket socket) { on_accept(error, std::move(socket)); });
}

void TcpSlaveServer::on_accept(const error_code& error, tcp::socket socket) {
    if (error == asio::error::operation_aborted) return;
    if (!error) {
        if (!allowed(socket) || !make_room(socket)) {
            accept();
            return;
        }
        // Requests and replies are small and answered one by one: Nagle would only add latency.
        error_code ignored;
        socket.set_option(tcp::no_delay(true), ignored);
        auto connection = std::make_shared<detail::TcpSlaveConnection>(slave_, *this, mailbox_, std::move(socket));
        connections_.emplace(connection.get(), connection);
        slave_.count(Slave::ConnectionEvent::accepted);
        connection->start();
        watch_idle();
        accept();
        return;
    }
    if (concerns_one_client(error)) {
        accept();
        return;
    }
    if (slave_.tracing()) {
        slave_.trace(TraceDirection::discarded, {}, "accepting a connection failed (" + error.message() + "); retrying shortly");
    }
    accept_pause_.expires_after(slave_.options().tcp.accept_retry_delay);
    accept_pause_.async_wait([this](const error_code& waited) {
        if (!waited) accept();
    });
}

void TcpSlaveServer::log(const std::string& line) const {
    if (slave_.options().connection_log) slave_.options().connection_log(line);
    if (slave_.tracing()) slave_.trace(TraceDirection::discarded, {}, line);
}

// A client whose address is outside TcpAccess::allow is closed before it is read, and counted.
bool TcpSlaveServer::allowed(tcp::socket& newcomer) {
    error_code error;
    const auto endpoint = newcomer.remote_endpoint(error);
    if (!error && slave_.options().access.allow.allows(endpoint.address())) return true;
    if (!error) {
        log(fmt::format("Modbus TCP: refused a client from {}:{}: its address is not in the allow list",
                        endpoint.address().to_string(), endpoint.port()));
    }
    slave_.count(Slave::ConnectionEvent::not_allowed);
    newcomer.close(error);
    return false;
}

// The connection to close for a newcomer at max_connections: one whose client has ended its
// side (it wants nothing more), else an idle one that never sent a whole request (a socket
// opened and left), else the idle one least recently active. None when every connection has a
// request in progress. A linear pass: it runs only when the server is full, over at most
// max_connections entries.
TcpSlaveServer::Connection TcpSlaveServer::eviction_candidate() const {
    Connection chosen;
    auto rank = [](const detail::TcpSlaveConnection& c) { return c.ended_by_client() ? 0 : !c.served_any() ? 1 : 2; };
    for (const auto& [key, connection] : connections_) {
        if (!connection->ended_by_client() && !connection->idle()) continue;
        if (!chosen || rank(*connection) < rank(*chosen) ||
            (rank(*connection) == rank(*chosen) && connection->last_active() < chosen->last_active())) {
            chosen = connection;
        }
    }
    return chosen;
}

// At max_connections a newcomer is admitted by closing the idlest connection; false (and the
// newcomer closed) when every connection is busy.
bool TcpSlaveServer::make_room(tcp::socket& newcomer) {
    const std::size_t limit = slave_.options().tcp.max_connections;
    if (limit == 0 || connections_.size() < limit) return true;
    if (auto idlest = eviction_candidate()) {
        const auto idle_for = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - idlest->last_active());
        log(fmt::format("Modbus TCP: {} connections open (the most allowed): closed the one from {}, idle {} ms, to admit a new client",
                        connections_.size(), idlest->peer(), idle_for.count()));
        slave_.count(Slave::ConnectionEvent::evicted);
        idlest->close();  // calls forget(): the map has room again
        return true;
    }
    error_code ignored;
    const auto endpoint = newcomer.remote_endpoint(ignored);
    log(fmt::format("Modbus TCP: {} connections open (the most allowed), each with a request in progress: refused a new "
                    "client from {}:{}",
                    connections_.size(), endpoint.address().to_string(), endpoint.port()));
    slave_.count(Slave::ConnectionEvent::refused);
    newcomer.close(ignored);
    return false;
}

// One timer for every connection, at the earliest moment one of them could have been idle for
// idle_timeout; a connection with a request in progress cannot be idle before now + timeout.
// Nothing is armed while no connection is open, so an idle server still never wakes up.
void TcpSlaveServer::watch_idle() {
    const auto timeout = slave_.options().tcp.idle_timeout;
    if (timeout <= std::chrono::milliseconds::zero() || idle_check_armed_ || connections_.empty() || stopping_) return;
    const auto now = std::chrono::steady_clock::now();
    auto earliest = now + timeout;
    for (const auto& [key, connection] : connections_) {
        if (connection->idle()) earliest = std::min(earliest, connection->last_active() + timeout);
    }
    idle_check_armed_ = true;
    idle_check_.expires_at(earliest);
    idle_check_.async_wait([this](const error_code& error) {
        idle_check_armed_ = false;
        if (!error) close_idle();
    });
}

void TcpSlaveServer::close_idle() {
    const auto timeout = slave_.options().tcp.idle_timeout;
    const auto now = std::chrono::steady_clock::now();
    std::vector<Connection> expired;
    for (const auto& [key, connection] : connections_) {
        if (connection->idle() && now - connection->last_active() >= timeout) expired.push_back(connection);
    }
    for (const auto& connection : expired) {
        log(fmt::format("Modbus TCP: closed the connection from {}: idle for {} ms (idle timeout)", connection->peer(),
                        std::chrono::duration_cast<std::chrono::milliseconds>(now - connection->last_active()).count()));
        slave_.count(Slave::ConnectionEvent::idle_closed);
        connection->close();
    }
    watch_idle();
}

// No new connections; each open one stops reading, sends the replies it owes (a reply on its
// way from a slow handler, such as a gateway's serial line, still reaches the client that asked
// before stop was requested) and closes. The loop ends when the last has closed, or after a
// bound, as a client that does not read must not hold the stop up.
void TcpSlaveServer::stop_gracefully() {
    if (stopping_) return;
    stopping_ = true;
    error_code ignored;
    acceptor_.close(ignored);
    accept_pause_.cancel();
    idle_check_.cancel();
    if (connections_.empty()) {
        loop_.stop();
        return;
    }
    auto open = connections_;  // closing may call forget() and change the map
    for (auto& [key, connection] : open) connection->close_after_replies({});
    stop_limit_.expires_after(std::chrono::seconds(3));
    stop_limit_.async_wait([this](const error_code& error) {
        if (!error) loop_.stop();
    });
}

void TcpSlaveServer::shut_down() {
    mailbox_->close();  // replies still to come are dropped from now on
    error_code ignored;
    acceptor_.close(ignored);
    accept_pause_.cancel();
    idle_check_.cancel();
    auto open = std::move(connections_);
    connections_.clear();
    for (auto& [key, connection] : open) connection->close();
}

}  // namespace

Result<void> serve_tcp_clients(Slave& slave, transport::TcpListener& listener, std::stop_token stop, asio::io_context* loop) {
    TcpSlaveServer server(slave, loop);
    return server.serve(listener, std::move(stop));
}

}  // namespace loopwire::session
