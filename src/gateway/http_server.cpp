#include "gateway/http_server.hpp"

#include <array>
#include <map>
#include <mutex>
#include <optional>
#include <thread>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <fmt/format.h>

namespace loopwire::gateway {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using asio::ip::tcp;
using boost::system::error_code;

std::string to_string(beast::string_view text) { return std::string(text.data(), text.size()); }

// An error body the server itself writes: its messages are fixed texts with nothing to escape.
std::string error_json(std::string_view message) { return fmt::format("{{\"error\": \"{}\"}}", message); }

HttpResponse error_response(unsigned status, std::string_view message) {
    HttpResponse response;
    response.status = status;
    response.body = error_json(message);
    return response;
}

// The queue between the poll threads and one event stream: text waiting to be written, bounded.
struct EventQueue {
    std::mutex mutex;
    std::string pending;
    bool overflowed = false;
    bool flush_posted = false;
};

}  // namespace

class Connection;

struct HttpServer::State {
    State(const HttpServerSettings& s, HttpHandler& h) : settings(s), handler(h), workers(s.workers) {}

    HttpServerSettings settings;
    HttpHandler& handler;
    // Before the loop, so still there when the loop's pending handlers release the last
    // connections.
    std::map<Connection*, std::weak_ptr<Connection>> connections;  // the network thread's
    // Declared before what uses it, destroyed after: pending handlers (and the connections they
    // hold) go with it.
    asio::io_context loop{1};
    asio::thread_pool workers;
    tcp::acceptor acceptor{loop};
    asio::steady_timer accept_pause{loop};
    std::uint16_t port = 0;
    bool stopping = false;  // the network thread's
    std::once_flag stopped;
    std::thread thread;

    void accept();
    void on_accept(const error_code& error, tcp::socket socket);
    void shut_down();
};

// One client's connection, on the network thread only (but for its event queue).
class Connection : public std::enable_shared_from_this<Connection> {
public:
    Connection(HttpServer::State& server, tcp::socket socket) : server_(server), stream_(std::move(socket)), heartbeat_(server.loop) {}
    ~Connection() {
        subscription_.reset();
        server_.connections.erase(this);
    }

    void start() { read_request(); }

    // Ends the connection now, or after the response of the blocking work under way.
    void stop() {
        if (waiting_for_worker_) {
            close_after_response_ = true;
            return;
        }
        close();
    }

private:
    void read_request() {
        parser_.emplace();
        parser_->header_limit(static_cast<std::uint32_t>(server_.settings.header_limit));
        parser_->body_limit(server_.settings.body_limit);
        // The whole request within the timeout: a client that sends half of one and stalls is
        // closed, as is one that trickles it a byte at a time.
        stream_.expires_after(server_.settings.read_timeout);
        http::async_read_header(stream_, buffer_, *parser_,
                                [self = shared_from_this()](const error_code& error, std::size_t) { self->on_header(error); });
    }

    void on_header(const error_code& error) {
        if (error) return refuse_unreadable(error);
        const auto& header = parser_->get();
        if (header.payload_size() && *header.payload_size() > server_.settings.body_limit) {
            return send(too_large(), true);
        }
        if (beast::iequals(header[http::field::expect], "100-continue")) {
            continue_ = std::make_shared<std::string>("HTTP/1.1 100 Continue\r\n\r\n");
            asio::async_write(stream_, asio::buffer(*continue_), [self = shared_from_this()](const error_code& e, std::size_t) {
                if (e) return self->close();
                self->read_body();
            });
            return;
        }
        read_body();
    }

    void read_body() {
        http::async_read(stream_, buffer_, *parser_, [self = shared_from_this()](const error_code& error, std::size_t) {
            if (error) return self->refuse_unreadable(error);
            self->dispatch();
        });
    }

    HttpResponse too_large() const {
        return error_response(413, fmt::format("the request body is larger than {} bytes", server_.settings.body_limit));
    }

    // A request that could not be read: answered where the client can still use an answer.
    void refuse_unreadable(const error_code& error) {
        if (error == http::error::body_limit) return send(too_large(), true);
        if (error == http::error::header_limit) {
            return send(error_response(431, fmt::format("the request's headers are larger than {} bytes",
                                                        server_.settings.header_limit)), true);
        }
        if (error == http::error::end_of_stream || error == beast::error::timeout || error == asio::error::operation_aborted ||
            error == asio::error::connection_reset || error == asio::error::eof || error == http::error::partial_message) {
            return close();
        }
        send(error_response(400, "malformed HTTP request"), true);
    }

    void dispatch() {
        const auto& message = parser_->get();
        keep_alive_ = message.keep_alive();
        HttpRequest request;
        request.method = std::string(message.method_string().data(), message.method_string().size());
        const std::string_view target(message.target().data(), message.target().size());
        const auto question = target.find('?');
        request.path = std::string(target.substr(0, question));
        if (question != std::string_view::npos) request.query = std::string(target.substr(question + 1));
        request.authorization = to_string(message[http::field::authorization]);
        request.if_none_match = to_string(message[http::field::if_none_match]);
        request.body = message.body();
        HttpOutcome outcome = server_.handler.handle(request);
        if (outcome.events) return start_events(outcome.events);
        if (outcome.blocking) return run_blocking(std::move(outcome.blocking));
        send(outcome.response, false);
    }

    // On a worker, then back here with its response; the connection reads nothing meanwhile.
    void run_blocking(std::function<HttpResponse()> work) {
        waiting_for_worker_ = true;
        stream_.expires_never();
        // The guard keeps the network loop running until the response is back, even when stop()
        // has closed everything else.
        asio::post(server_.workers, [self = shared_from_this(), work = std::move(work),
                                     guard = asio::make_work_guard(server_.loop)]() mutable {
            HttpResponse response = work();
            auto& loop = self->server_.loop;
            asio::post(loop, [self = std::move(self), response = std::move(response)] {
                self->waiting_for_worker_ = false;
                self->send(response, false);
            });
        });
    }

    void send(const HttpResponse& response, bool close_after) {
        if (closed_) return;
        auto message = std::make_shared<http::response<http::string_body>>(static_cast<http::status>(response.status), 11);
        message->set(http::field::server, "loopwire");
        message->set(http::field::content_type, response.content_type);
        for (const auto& [name, value] : response.headers) message->set(name, value);
        message->body() = response.body;
        const bool again = keep_alive_ && !close_after && !close_after_response_ && !server_.stopping;
        message->keep_alive(again);
        message->prepare_payload();
        stream_.expires_after(server_.settings.read_timeout);
        http::async_write(stream_, *message, [self = shared_from_this(), message, again](const error_code& error, std::size_t) {
            if (error) return self->close();
            if (again) return self->read_request();
            self->finish();
        });
    }

    // After the last response: no more to send, and what the client still sends (the rest of a
    // refused body) is read and dropped for a moment, so that closing does not reset the
    // connection before the client has read the response.
    void finish() {
        error_code ignored;
        stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
        stream_.expires_after(std::chrono::seconds(1));
        drain_ = std::make_shared<std::array<char, 4096>>();
        drain_some(0);
    }

    void drain_some(std::size_t drained) {
        if (drained > server_.settings.body_limit * 4) return close();
        stream_.async_read_some(asio::buffer(*drain_), [self = shared_from_this(), drained](const error_code& error, std::size_t n) {
            if (error) return self->close();
            self->drain_some(drained + n);
        });
    }

    // --- server-sent events -------------------------------------------------------------------

    void start_events(const std::function<ValueSubscription(EventSender)>& subscribe) {
        queue_ = std::make_shared<EventQueue>();
        queue_->pending =
            "HTTP/1.1 200 OK\r\nServer: loopwire\r\nContent-Type: text/event-stream\r\nCache-Control: no-cache\r\n"
            "Connection: close\r\nX-Accel-Buffering: no\r\n\r\n";
        stream_.expires_never();
        std::weak_ptr<Connection> weak = shared_from_this();
        subscription_ = subscribe([queue = queue_, weak, &loop = server_.loop, limit = server_.settings.event_queue_limit](
                                      const std::string& event) {
            std::lock_guard lock(queue->mutex);
            if (queue->overflowed) return;
            if (queue->pending.size() + event.size() > limit) {
                // Too far behind: dropped (the client reconnects and starts from the full picture).
                queue->overflowed = true;
                queue->pending.clear();
            } else {
                queue->pending += event;
            }
            if (std::exchange(queue->flush_posted, true)) return;
            asio::post(loop, [weak] {
                if (auto self = weak.lock()) self->flush_events();
            });
        });
        watch_for_close();
        beat();
        flush_events();
    }

    void flush_events() {
        if (closed_ || writing_) return;
        bool overflowed = false;
        {
            std::lock_guard lock(queue_->mutex);
            out_ = std::move(queue_->pending);
            queue_->pending.clear();
            overflowed = queue_->overflowed;
            queue_->flush_posted = false;
        }
        if (overflowed) return close();
        if (out_.empty()) return;
        writing_ = true;
        stream_.expires_after(server_.settings.read_timeout);
        asio::async_write(stream_, asio::buffer(out_), [self = shared_from_this()](const error_code& error, std::size_t) {
            self->writing_ = false;
            if (error) return self->close();
            self->stream_.expires_never();
            self->flush_events();
        });
    }

    // The client sends nothing more on an event stream: a read ends only when it goes.
    void watch_for_close() {
        drain_ = std::make_shared<std::array<char, 4096>>();
        stream_.socket().async_read_some(asio::buffer(*drain_), [self = shared_from_this()](const error_code& error, std::size_t) {
            if (error) return self->close();
            self->watch_for_close();
        });
    }

    void beat() {
        heartbeat_.expires_after(server_.settings.event_heartbeat);
        heartbeat_.async_wait([self = shared_from_this()](const error_code& error) {
            if (error || self->closed_) return;
            {
                std::lock_guard lock(self->queue_->mutex);
                self->queue_->pending += ": keep-alive\n\n";
            }
            self->flush_events();
            self->beat();
        });
    }

public:
    void close() {
        if (std::exchange(closed_, true)) return;
        subscription_.reset();  // waits for a callback under way on a poll thread; it only queues
        heartbeat_.cancel();
        error_code ignored;
        stream_.socket().shutdown(tcp::socket::shutdown_both, ignored);
        stream_.close();
        server_.connections.erase(this);
    }

private:
    HttpServer::State& server_;
    beast::tcp_stream stream_;
    beast::flat_buffer buffer_;
    std::optional<http::request_parser<http::string_body>> parser_;
    std::shared_ptr<std::string> continue_;
    std::shared_ptr<std::array<char, 4096>> drain_;
    bool keep_alive_ = false;
    bool closed_ = false;
    bool waiting_for_worker_ = false;
    bool close_after_response_ = false;
    // Event streams:
    std::shared_ptr<EventQueue> queue_;
    ValueSubscription subscription_;
    asio::steady_timer heartbeat_;
    std::string out_;
    bool writing_ = false;
};

void HttpServer::State::accept() {
    acceptor.async_accept(loop, [this](const error_code& error, tcp::socket socket) { on_accept(error, std::move(socket)); });
}

void HttpServer::State::on_accept(const error_code& error, tcp::socket socket) {
    if (stopping || error == asio::error::operation_aborted) return;
    if (error) {
        // Out of descriptors or memory: accepting again at once would fail just as fast.
        accept_pause.expires_after(std::chrono::milliseconds(100));
        accept_pause.async_wait([this](const error_code& e) {
            if (!e) accept();
        });
        return;
    }
    if (connections.size() >= settings.max_connections) {
        // Told so in one small write the socket buffer takes at once, then closed.
        const std::string body = error_json(fmt::format("too many connections (at most {}); try again later", settings.max_connections));
        const std::string refusal = fmt::format(
            "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\nContent-Length: {}\r\nRetry-After: 1\r\n"
            "Connection: close\r\n\r\n{}", body.size(), body);
        error_code ignored;
        socket.non_blocking(true, ignored);
        socket.write_some(asio::buffer(refusal), ignored);
        socket.shutdown(tcp::socket::shutdown_both, ignored);
        socket.close(ignored);
    } else {
        auto connection = std::make_shared<Connection>(*this, std::move(socket));
        connections[connection.get()] = connection;
        connection->start();
    }
    accept();
}

void HttpServer::State::shut_down() {
    stopping = true;
    error_code ignored;
    acceptor.close(ignored);
    accept_pause.cancel();
    auto open = connections;  // stop() may erase
    for (auto& [raw, weak] : open) {
        if (auto connection = weak.lock()) connection->stop();
    }
}

HttpServer::HttpServer(std::unique_ptr<State> state) : state_(std::move(state)) {}

HttpServer::~HttpServer() { stop(); }

Result<std::unique_ptr<HttpServer>> HttpServer::open(const HttpServerSettings& settings, HttpHandler& handler) {
    auto state = std::make_unique<State>(settings, handler);
    const bool ipv6 = settings.host.find(':') != std::string::npos;
    const std::string where = fmt::format("http.listen {}{}{}:{}", ipv6 ? "[" : "", settings.host, ipv6 ? "]" : "", settings.port);
    error_code error;
    tcp::resolver resolver(state->loop);
    auto endpoints = resolver.resolve(settings.host, std::to_string(settings.port),
                                      tcp::resolver::passive | tcp::resolver::numeric_service, error);
    if (error || endpoints.empty()) {
        return make_error(ErrorKind::link, fmt::format("{}: cannot resolve the address: {}", where, error.message()));
    }
    const tcp::endpoint endpoint = *endpoints.begin();
    state->acceptor.open(endpoint.protocol(), error);
    if (!error) state->acceptor.set_option(tcp::acceptor::reuse_address(true), error);
    if (!error) state->acceptor.bind(endpoint, error);
    if (!error) state->acceptor.listen(asio::socket_base::max_listen_connections, error);
    if (error) {
        return make_error(ErrorKind::link, fmt::format("{}: {}{}", where, error.message(),
                                                       error == asio::error::address_in_use
                                                           ? " (another program listens there: choose another port in [http] listen)"
                                                           : ""));
    }
    state->port = state->acceptor.local_endpoint().port();
    state->accept();
    state->thread = std::thread([s = state.get()] { s->loop.run(); });
    return std::unique_ptr<HttpServer>(new HttpServer(std::move(state)));
}

std::uint16_t HttpServer::port() const { return state_->port; }

void HttpServer::stop() {
    std::call_once(state_->stopped, [this] {
        asio::post(state_->loop, [s = state_.get()] { s->shut_down(); });
        // Returns once every connection is closed: the blocking work under way has answered.
        state_->thread.join();
        state_->workers.join();
    });
}

}  // namespace loopwire::gateway
