#pragma once
// The gateway's HTTP server: connections, limits and timeouts, with Boost.Beast kept inside
// http_server.cpp. What a request means is the handler's business (gateway/http_api.hpp); the
// server reads requests, hands them over, and sends what comes back, on one network thread: in
// the gateway the engine's (gateway/engine.hpp), with the polls and the Modbus TCP front.
//
// Threads: handle() runs on the network thread and must not block (it would hold up the polls);
// work that waits (a write waits for its line, a history query for the database) comes back as
// HttpOutcome::deferred, which starts it and is answered
// through the responder from whatever thread finishes it, so a slow line never holds up other
// clients or another line's writes. An event stream's `send` is called from any thread (the poll
// groups'); it only queues, bounded per client: a client that cannot keep up, or takes nothing
// for `send_timeout`, is dropped rather than let its queue grow or slow anyone down.
//
// Limits, so that slow or hostile clients cannot take the server: a request's header within
// `header_timeout` and the whole of it within `read_timeout` (a client trickling a byte at a time
// is closed as one that stalls), `max_connections` in all and `max_connections_per_client` from
// one address (beyond, 503 and 429, and closed), header and body sizes (431, 413). Event streams
// stay open for as long as their clients like, so they may hold only a share of the connections
// (`max_event_streams`, `max_event_streams_per_client`; beyond, 503 and 429): the rest are for
// requests, which end. A newcomer at a connection limit takes the place of the connection that
// has waited longest for a request's header (an idle keep-alive one, or a client too slow to send
// one), so clients that open connections and send nothing, however fast they reconnect, cannot
// lock out a request either.
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/result.hpp"
#include "gateway/value_cache.hpp"
#include "transport/address_allow_list.hpp"

namespace boost::asio {
class io_context;
}

namespace loopwire::gateway {

struct HttpRequest {
    std::string method;         // "GET", "POST", ...
    std::string host;           // the Host header, as sent ("127.0.0.1:8080"); empty when absent
    std::string path;           // "/api/devices/furnace", as sent (still percent-encoded)
    std::string query;          // what follows '?', as sent
    std::string authorization;  // the Authorization header
    std::string if_none_match;  // the If-None-Match header
    std::string cookie;         // the Cookie header
    std::string content_type;   // the Content-Type header
    std::string csrf_token;     // the X-CSRF-Token header
    std::string body;
    std::string client;         // the client's address ("127.0.0.1"), for the audit of writes
};

struct HttpResponse {
    unsigned status = 200;
    std::string content_type = "application/json";
    std::string body;
    std::vector<std::pair<std::string, std::string>> headers;  // besides Content-Type and -Length
};

// Sends one server-sent event's text ("data: ...\n\n"); callable from any thread.
using EventSender = std::function<void(const std::string& event)>;

// Sends the response of deferred work; callable once, from any thread. Until it is called the
// connection reads nothing more, and a stopping server waits for it: call it exactly once.
using HttpResponder = std::function<void(HttpResponse)>;

struct HttpOutcome {
    HttpResponse response;                      // sent at once, unless one of these is set:
    // Starts work that waits (on the network thread: must not block itself) and answers it
    // through the responder once done.
    std::function<void(HttpResponder)> deferred;
    // Starts an event stream: the server sends the headers, then every event given to the
    // sender, until the client goes or the subscription's queue overflows.
    std::function<ValueSubscription(EventSender)> events;
};

class HttpHandler {
public:
    virtual ~HttpHandler() = default;
    virtual HttpOutcome handle(const HttpRequest& request) = 0;
};

struct HttpServerSettings {
    std::string host = "127.0.0.1";
    std::uint16_t port = 0;
    std::chrono::milliseconds read_timeout{10000};  // for the whole of a request, and each write
    // For a request's header, from the connection or the response before: no longer than
    // read_timeout (the shorter of the two counts).
    std::chrono::milliseconds header_timeout{5000};
    std::size_t max_connections = 64;               // more are answered 503 and closed
    std::size_t max_connections_per_client = 8;     // from one address; more are answered 429 and closed
    std::size_t max_event_streams = 32;             // of max_connections; more are answered 503
    std::size_t max_event_streams_per_client = 4;   // from one address; more are answered 429
    std::size_t header_limit = 8 * 1024;            // 431 beyond
    std::size_t body_limit = 64 * 1024;             // 413 beyond
    std::size_t event_queue_limit = 1024 * 1024;    // bytes an event stream may have waiting
    std::chrono::milliseconds send_timeout{10000};  // an event stream's client that takes nothing this long is dropped
    std::chrono::milliseconds event_heartbeat{15000};  // a comment line keeps idle streams alive
    transport::AddressAllowList allow;              // others are closed at accept; empty: everyone
    // PEM files; both set: the server speaks HTTPS alone (TLS 1.2 and 1.3, OpenSSL's default
    // ciphers at security level 2), and every response says Strict-Transport-Security. Both
    // empty: plain HTTP.
    std::string certificate;
    std::string private_key;
};

// Whether `certificate` (PEM, the server's certificate and its chain) and `private_key` (PEM,
// its key) can serve TLS: both read, and the key the certificate's. The error says which file
// and what is wrong with it, without a location (the caller knows where they were named).
Result<void> check_tls_files(const std::string& certificate, const std::string& private_key);

// What the server makes of the bytes of one request, without a socket: the request, or the
// response that refuses it (400 malformed or with two Hosts, 413, 431, 501 for a Transfer-Encoding
// other than chunked), or neither while more bytes are needed.
// The network code reads requests with the same parser settings and the same mapping.
struct ParsedHttpRequest {
    std::optional<HttpRequest> request;
    std::optional<HttpResponse> refusal;
};
ParsedHttpRequest parse_http_request(std::string_view bytes, const HttpServerSettings& settings);

// The listening socket of the HTTP API, which may outlive the servers that accept on it: a reload
// that leaves [http] listen alone keeps it, so the port stays the same (also
// one the kernel chose) and a client connecting while the next gateway opens waits in its
// backlog instead of being refused.
class HttpListener {
public:
    // Binds and listens; the error names the address and, when it is taken, what to do.
    static Result<HttpListener> open(const std::string& host, std::uint16_t port);
    HttpListener(HttpListener&& other) noexcept;
    HttpListener& operator=(HttpListener&& other) noexcept;
    HttpListener(const HttpListener&) = delete;
    HttpListener& operator=(const HttpListener&) = delete;
    ~HttpListener();

    // Whether it is the one [http] listen asks for: the same address, and the same port asked
    // for (0 for one the kernel chose).
    bool listens_as(const std::string& host, std::uint16_t port) const { return host == host_ && port == asked_port_; }
    std::uint16_t port() const { return port_; }
    int fd() const { return fd_; }
    bool ipv6() const { return ipv6_; }

    // A keep-alive connection a stopping server handed over for the next server on this
    // listener (HttpServer::stop with hand_over: a reload keeps the clients'
    // connections): its socket, and the bytes of its next request already read.
    // Owns the socket until release().
    class Parked {
    public:
        Parked(int fd, std::string buffered) : fd_(fd), buffered_(std::move(buffered)) {}
        Parked(Parked&& other) noexcept : fd_(std::exchange(other.fd_, -1)), buffered_(std::move(other.buffered_)) {}
        Parked& operator=(Parked&&) = delete;
        Parked(const Parked&) = delete;
        Parked& operator=(const Parked&) = delete;
        ~Parked();
        int release() { return std::exchange(fd_, -1); }
        const std::string& buffered() const { return buffered_; }

    private:
        int fd_;
        std::string buffered_;
    };
    // From the stopping server's loop; the listener owns the socket from here on (closed with it
    // unless taken).
    void park(int fd, std::string buffered);
    // For the next server.
    std::vector<Parked> take_parked();
    // Clients closed as outside [http] allow, by every server on this listener: the count goes on
    // across reloads, as the listener does.
    void count_not_allowed() { not_allowed_->fetch_add(1, std::memory_order_relaxed); }
    std::uint64_t not_allowed() const { return not_allowed_->load(std::memory_order_relaxed); }

private:
    HttpListener(std::string host, std::uint16_t asked_port, std::uint16_t port, int fd, bool ipv6)
        : host_(std::move(host)), asked_port_(asked_port), port_(port), fd_(fd), ipv6_(ipv6) {}
    std::string host_;
    std::uint16_t asked_port_ = 0;
    std::uint16_t port_ = 0;
    int fd_ = -1;
    bool ipv6_ = false;
    std::unique_ptr<std::mutex> parked_mutex_ = std::make_unique<std::mutex>();
    std::vector<Parked> parked_;  // guarded by *parked_mutex_
    std::unique_ptr<std::atomic<std::uint64_t>> not_allowed_ = std::make_unique<std::atomic<std::uint64_t>>(0);
};

class HttpServer {
public:
    // Listens at once (the error names the address); serves until stop() on `loop`, run by its
    // owner for as long as the server exists (the gateway's engine), or on a thread of its own
    // when none is given.
    // With `listener`, it accepts on that (kept by the caller; settings.host and port are then
    // its), and leaves it listening when it stops; the connections parked there by the server
    // before it are served on from where they were (within this server's limits).
    static Result<std::unique_ptr<HttpServer>> open(const HttpServerSettings& settings, HttpHandler& handler,
                                                    boost::asio::io_context* loop = nullptr,
                                                    HttpListener* listener = nullptr);
    ~HttpServer();
    HttpServer(const HttpServer&) = delete;
    HttpServer& operator=(const HttpServer&) = delete;

    std::uint16_t port() const;  // the one the kernel chose for port 0
    // Clients closed at accept so far: their address is outside settings.allow. Any thread.
    std::uint64_t not_allowed() const;

    // Reads settings.certificate and private_key again (a reload whose configuration names the
    // same files, which were replaced): connections accepted from here on get the new ones,
    // those open keep what they began with. An error (a file that does not load) changes
    // nothing. Any thread; nothing to do without TLS.
    Result<void> reload_certificate();

    // Stops accepting, ends event streams and idle connections, lets the blocking work under way
    // finish and answer, then closes everything. Idempotent. Never on the loop's own thread: it
    // waits for the loop to close the connections.
    // With `hand_over` (a reload whose next server accepts on the same listener), keep-alive
    // connections are not closed but parked in the listener once the response under way has
    // gone out, keep-alive: their clients see no reload. Event streams end either way (a stream
    // follows this server's values; the client reconnects to the next one's). Over TLS none is
    // handed over (the session's state is the server's, not the socket's): keep-alive ones are
    // closed once their response has gone, and the clients reconnect.
    void stop(bool hand_over = false);

    struct State;

private:
    explicit HttpServer(std::shared_ptr<State> state);
    std::shared_ptr<State> state_;
};

}  // namespace loopwire::gateway
