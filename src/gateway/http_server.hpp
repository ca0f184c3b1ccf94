#pragma once
// The gateway's HTTP server: connections, limits and timeouts, with Boost.Beast kept inside
// http_server.cpp. What a request means is the handler's business (gateway/http_api.hpp); the
// server reads requests, hands them over, and sends what comes back, on one network thread.
//
// Threads: handle() runs on the network thread and must not block; work that blocks (a write
// waits for its line) comes back as HttpOutcome::blocking and runs on a small worker pool, so a
// slow line never holds up other clients. An event stream's `send` is called from any thread
// (the poll groups'); it only queues, bounded per client: a client that cannot keep up is
// dropped rather than let its queue grow or slow anyone down.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "common/result.hpp"
#include "gateway/value_cache.hpp"

namespace loopwire::gateway {

struct HttpRequest {
    std::string method;         // "GET", "POST", ...
    std::string path;           // "/api/devices/furnace", as sent (still percent-encoded)
    std::string query;          // what follows '?', as sent
    std::string authorization;  // the Authorization header
    std::string if_none_match;  // the If-None-Match header
    std::string body;
};

struct HttpResponse {
    unsigned status = 200;
    std::string content_type = "application/json";
    std::string body;
    std::vector<std::pair<std::string, std::string>> headers;  // besides Content-Type and -Length
};

// Sends one server-sent event's text ("data: ...\n\n"); callable from any thread.
using EventSender = std::function<void(const std::string& event)>;

struct HttpOutcome {
    HttpResponse response;                      // sent at once, unless one of these is set:
    std::function<HttpResponse()> blocking;     // runs on a worker; its response is sent
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
    std::size_t max_connections = 64;               // more are answered 503 and closed
    std::size_t header_limit = 8 * 1024;            // 431 beyond
    std::size_t body_limit = 64 * 1024;             // 413 beyond
    std::size_t event_queue_limit = 1024 * 1024;    // bytes an event stream may have waiting
    std::chrono::milliseconds event_heartbeat{15000};  // a comment line keeps idle streams alive
    unsigned workers = 2;                           // threads for blocking work
};

class HttpServer {
public:
    // Listens at once (the error names the address); serves on its own thread until stop().
    static Result<std::unique_ptr<HttpServer>> open(const HttpServerSettings& settings, HttpHandler& handler);
    ~HttpServer();
    HttpServer(const HttpServer&) = delete;
    HttpServer& operator=(const HttpServer&) = delete;

    std::uint16_t port() const;  // the one the kernel chose for port 0

    // Stops accepting, ends event streams and idle connections, lets the blocking work under way
    // finish and answer, then closes everything. Idempotent.
    void stop();

    struct State;

private:
    explicit HttpServer(std::unique_ptr<State> state);
    std::unique_ptr<State> state_;
};

}  // namespace loopwire::gateway
