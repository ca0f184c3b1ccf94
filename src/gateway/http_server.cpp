#include "gateway/http_server.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <condition_variable>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <fmt/format.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>

#include "common/thread_name.hpp"

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

HttpResponse too_large(const HttpServerSettings& settings) {
    return error_response(413, fmt::format("the request body is larger than {} bytes", settings.body_limit));
}

// The most a connection buffers of one request: its headers and body at their limits, and room
// for the chunked framing around the body. Chunk-size lines, their extensions and the trailer
// count against neither limit in the parser: unbounded, one connection that never ends a chunk
// line grew the gateway by gigabytes.
std::size_t read_buffer_limit(const HttpServerSettings& settings) { return settings.header_limit + settings.body_limit + 16 * 1024; }

HttpResponse request_too_large(const HttpServerSettings& settings) {
    return error_response(413, fmt::format("the request is larger than {} bytes with its headers and chunked framing",
                                           read_buffer_limit(settings)));
}

// What a request that cannot be read gets: none when nothing can usefully be said (the client
// went, or stalled past read_timeout), and the connection is just closed.
std::optional<HttpResponse> refusal_for(const error_code& error, const HttpServerSettings& settings) {
    if (error == http::error::body_limit) return too_large(settings);
    if (error == http::error::buffer_overflow) return request_too_large(settings);
    if (error == http::error::header_limit) {
        return error_response(431, fmt::format("the request's headers are larger than {} bytes", settings.header_limit));
    }
    if (error == http::error::end_of_stream || error == beast::error::timeout || error == asio::error::operation_aborted ||
        error == asio::error::connection_reset || error == asio::error::eof || error == http::error::partial_message) {
        return std::nullopt;
    }
    return error_response(400, "malformed HTTP request");
}

using RequestParser = http::request_parser<http::string_body>;

// What the parser has taken of a header still incomplete, as text again: its request line and
// the field lines it has parsed (the parser keeps them, not their bytes), so that the next server
// reads the same request from the start. Empty before the request line is complete.
std::string header_so_far(const http::request<http::string_body>& message) {
    if (message.target().empty()) return {};
    std::string text = fmt::format("{} {} HTTP/{}.{}\r\n", to_string(message.method_string()), to_string(message.target()),
                                   message.version() / 10, message.version() % 10);
    for (const auto& field : message) text += fmt::format("{}: {}\r\n", to_string(field.name_string()), to_string(field.value()));
    return text;
}

void limit(RequestParser& parser, const HttpServerSettings& settings) {
    parser.header_limit(static_cast<std::uint32_t>(settings.header_limit));
    parser.body_limit(settings.body_limit);
}

// A request whose framing or target is ambiguous, refused before its body is read; the connection
// is closed after the answer, since where the next request would begin is not known. RFC 9112,
// 6.1: a Transfer-Encoding other than chunked (last) is not understood here, 501 (read as no body,
// the body would be taken for the next request); RFC 9110, 7.2 and RFC 9112, 3.2: more than one
// Host is a 400 (the first alone was checked against [http] hosts).
std::optional<HttpResponse> framing_refusal(const RequestParser& parser) {
    const auto& header = parser.get();
    if (header.count(http::field::host) > 1) return error_response(400, "the request has more than one Host header");
    if (header.count(http::field::transfer_encoding) > 0 && !parser.chunked()) {
        return error_response(501, "the request's Transfer-Encoding is not supported: send its body with Content-Length, or "
                                   "chunked");
    }
    return std::nullopt;
}

// The parsed message as the handler sees it: every text exactly as sent (the handler escapes
// what it repeats).
HttpRequest to_request(const http::request<http::string_body>& message) {
    HttpRequest request;
    request.method = to_string(message.method_string());
    request.host = to_string(message[http::field::host]);
    std::string_view target(message.target().data(), message.target().size());
    // RFC 9112, 3.2.2: a server must accept the absolute form ("http://host:port/path", as proxies
    // send it); its authority then stands for Host.
    for (const std::string_view scheme : {"http://", "https://"}) {
        const std::string_view start = target.substr(0, scheme.size());
        if (!beast::iequals(beast::string_view(start.data(), start.size()), beast::string_view(scheme.data(), scheme.size()))) {
            continue;
        }
        target.remove_prefix(scheme.size());
        const auto slash = target.find_first_of("/?");
        request.host = std::string(target.substr(0, slash));
        target = slash == std::string_view::npos ? std::string_view("/") : target.substr(slash);
        break;
    }
    const auto question = target.find('?');
    request.path = std::string(target.substr(0, question));
    if (question != std::string_view::npos) request.query = std::string(target.substr(question + 1));
    request.authorization = to_string(message[http::field::authorization]);
    request.if_none_match = to_string(message[http::field::if_none_match]);
    request.cookie = to_string(message[http::field::cookie]);
    request.content_type = to_string(message[http::field::content_type]);
    request.csrf_token = to_string(message["X-CSRF-Token"]);
    request.body = message.body();
    return request;
}

// One client address, as counted for max_connections_per_client: an IPv4 client reaching an
// IPv6 socket is the same client as over IPv4.
asio::ip::address client_of(const tcp::socket& socket) {
    error_code error;
    auto address = socket.remote_endpoint(error).address();
    if (address.is_v6() && address.to_v6().is_v4_mapped()) {
        return asio::ip::make_address_v4(asio::ip::v4_mapped, address.to_v6());
    }
    return address;
}

// The queue between the poll threads and one event stream: text waiting to be written, bounded.
struct EventQueue {
    std::mutex mutex;
    std::string pending;
    bool overflowed = false;
    bool flush_posted = false;
};

using PlainStream = beast::tcp_stream;
using TlsStream = beast::ssl_stream<beast::tcp_stream>;
using TlsContext = std::shared_ptr<asio::ssl::context>;

// What OpenSSL says went wrong: asio's error is the code it took from OpenSSL's queue; the rest
// of the queue (the same failure, further down) is dropped.
std::string openssl_error(const error_code& error) {
    ::ERR_clear_error();
    return error.message();
}

// The server's TLS: 1.2 and 1.3 only (1.0 and 1.1 are deprecated, RFC 8996), with OpenSSL's
// default ciphers at security level 2 (112 bits: no RSA or DH key under 2048 bits, no EC key under
// 224, no RC4, no compression), which is sound for a server that browsers and curl reach.
Result<TlsContext> load_tls(const std::string& certificate, const std::string& private_key) {
    auto context = std::make_shared<asio::ssl::context>(asio::ssl::context::tls_server);
    context->set_options(asio::ssl::context::default_workarounds | asio::ssl::context::no_sslv2 |
                         asio::ssl::context::no_sslv3 | asio::ssl::context::no_tlsv1 | asio::ssl::context::no_tlsv1_1 |
                         asio::ssl::context::single_dh_use);
    SSL_CTX* native = context->native_handle();
    ::SSL_CTX_set_min_proto_version(native, TLS1_2_VERSION);
    ::SSL_CTX_set_security_level(native, 2);
    ::ERR_clear_error();
    error_code error;
    context->use_certificate_chain_file(certificate, error);
    if (error) {
        return make_error(ErrorKind::usage, fmt::format("\"{}\" does not load as a certificate ({}); name the server's "
                                                        "certificate, PEM (with its chain after it)",
                                                        certificate, openssl_error(error)));
    }
    context->use_private_key_file(private_key, asio::ssl::context::pem, error);
    // A key that loads but is another certificate's is refused as it is loaded (asio's error is
    // OpenSSL's code).
    if (error && error.category() == asio::error::get_ssl_category() &&
        ERR_GET_REASON(static_cast<unsigned long>(error.value())) == X509_R_KEY_VALUES_MISMATCH) {
        ::ERR_clear_error();
        return make_error(ErrorKind::usage, fmt::format("\"{}\" is not the key of the certificate \"{}\"; name the key "
                                                        "the certificate was made for", private_key, certificate));
    }
    if (error) {
        return make_error(ErrorKind::usage, fmt::format("\"{}\" does not load as a private key ({}); name the "
                                                        "certificate's key, PEM, without a passphrase",
                                                        private_key, openssl_error(error)));
    }
    if (::SSL_CTX_check_private_key(native) != 1) {
        ::ERR_clear_error();
        return make_error(ErrorKind::usage, fmt::format("\"{}\" is not the key of the certificate \"{}\"; name the key "
                                                        "the certificate was made for", private_key, certificate));
    }
    return context;
}

}  // namespace

Result<void> check_tls_files(const std::string& certificate, const std::string& private_key) {
    auto loaded = load_tls(certificate, private_key);
    if (!loaded) return loaded.error();
    return {};
}

namespace {

// What the server knows of a connection, whatever it speaks (plain HTTP or TLS).
class ConnectionBase {
public:
    virtual ~ConnectionBase() = default;
    virtual void stop(bool hand_over) = 0;
    virtual void close() = 0;
    // Since when it has waited for a request's header (or a TLS handshake), while it does
    // (nullopt otherwise): what makes it one to close for a newcomer at a limit
    // (HttpServer::State::make_room).
    virtual std::optional<std::chrono::steady_clock::time_point> waiting_for_header_since() const = 0;
    virtual const asio::ip::address& client() const = 0;
};

}  // namespace

template <typename Stream>
class Connection;

// Shared by the server and every handler and connection on the loop: on a loop another runs,
// the last of them may go after the server has (an accept's cancelled completion).
struct HttpServer::State : std::enable_shared_from_this<HttpServer::State> {
    State(const HttpServerSettings& s, HttpHandler& h, asio::io_context* shared, HttpListener* kept)
        : settings(s), handler(h), listener(kept), own_loop(shared ? nullptr : std::make_unique<asio::io_context>(1)),
          loop(shared ? *shared : *own_loop) {}

    HttpServerSettings settings;
    HttpHandler& handler;
    HttpListener* listener;  // the caller's, kept across reloads; none when the server listens itself
    // Before the loop, so still there when the loop's pending handlers release the last
    // connections.
    std::map<ConnectionBase*, std::weak_ptr<ConnectionBase>> connections;  // the network thread's
    std::map<asio::ip::address, std::size_t> per_client;           // open connections by address
    std::size_t event_streams = 0;                                  // of `connections`
    std::map<asio::ip::address, std::size_t> streams_per_client;   // event streams by address
    // Declared before what uses it, destroyed after: pending handlers (and the connections they
    // hold) go with it. None on a loop another runs.
    std::unique_ptr<asio::io_context> own_loop;
    asio::io_context& loop;
    tcp::acceptor acceptor{loop};
    asio::steady_timer accept_pause{loop};
    std::uint16_t port = 0;
    bool stopping = false;     // the network thread's
    // Clients closed as outside settings.allow, at accept or adopted across a reload: the
    // listener's count when there is one (it goes on across reloads).
    std::atomic<std::uint64_t> not_allowed{0};
    void count_not_allowed() {
        if (listener) {
            listener->count_not_allowed();
        } else {
            not_allowed.fetch_add(1, std::memory_order_relaxed);
        }
    }
    // With TLS: what new connections take; a reload's certificate replaces it, while connections
    // open keep theirs (each holds its own).
    mutable std::mutex tls_mutex;
    TlsContext tls;  // guarded by tls_mutex; none for plain HTTP
    bool handing_over = false;  // the network thread's: stopping, keep-alive connections go to `listener`
    std::once_flag stopped;
    std::thread thread;  // none on a loop another runs
    // What a stop waits for: connections still there (their deferred work not yet answered, or
    // their closing not yet run) and responders not yet let go (Connection::Pending), and the
    // shut-down.
    std::mutex live_mutex;
    std::condition_variable live_changed;
    std::size_t live = 0;
    bool shut = false;

    void accept();
    void on_accept(const error_code& error, tcp::socket socket);
    std::optional<HttpResponse> over_limits(const asio::ip::address& client) const;
    std::optional<HttpResponse> over_stream_limits(const asio::ip::address& client) const;
    bool make_room(const asio::ip::address& client, bool from_client);
    void serve(tcp::socket socket, const asio::ip::address& client, std::string_view buffered);
    void adopt(std::vector<HttpListener::Parked> parked);
    void refuse(tcp::socket& socket, unsigned status, std::string_view reason, std::string_view message) const;
    TlsContext tls_context() const {
        std::lock_guard lock(tls_mutex);
        return tls;
    }
    void shut_down(bool hand_over);
    void count_live(int change);
};

// One client's connection, on the network thread only (but for its event queue). `Stream`: a
// PlainStream, or a TlsStream over one; the HTTP is the same, the TLS adds a handshake first.
template <typename Stream>
class Connection : public ConnectionBase, public std::enable_shared_from_this<Connection<Stream>> {
    static constexpr bool tls = std::is_same_v<Stream, TlsStream>;

public:
    Connection(std::shared_ptr<HttpServer::State> server, tcp::socket socket, asio::ip::address client, TlsContext context)
        : kept_(std::move(server)), server_(*kept_), client_(client), context_(std::move(context)),
          stream_(make_stream(std::move(socket), context_)), heartbeat_(server_.loop) {
        ++server_.per_client[client_];
        server_.count_live(+1);
    }
    ~Connection() override {
        subscription_.reset();
        let_go();
        server_.count_live(-1);
    }

    // `buffered`: what a server before this one had read of the next request (a connection
    // handed over across a reload).
    void start(std::string_view buffered) {
        if (buffered.size() > buffer_.max_size()) return close();  // more than this server's limits take
        buffer_.commit(asio::buffer_copy(buffer_.prepare(buffered.size()), asio::buffer(buffered.data(), buffered.size())));
        if constexpr (tls) {
            handshake();
        } else {
            read_request();
        }
    }

    // Ends the connection now, or after the response of the blocking work under way. Handing
    // over, a keep-alive connection goes to the listener instead once its response has gone.
    void stop(bool hand_over) override {
        if (hand_over && phase_ == Phase::header) return stop_reading();
        // A request being answered or its response sent goes on: parked by send() after.
        if (hand_over && (phase_ == Phase::answering || phase_ == Phase::writing)) return;
        // So does one whose body is coming, for a moment (a client sends a body right after its
        // header), not for read_timeout: one that trickles it must not hold up the reload.
        if (hand_over && phase_ == Phase::body) return wait_briefly_for_body();
        if (waiting_for_worker_) {
            close_after_response_ = true;
            return;
        }
        close();
    }

private:
    // Where a connection is, for a stop that hands it over.
    enum class Phase { header, body, answering, writing, finishing, events };

    static Stream make_stream(tcp::socket socket, const TlsContext& context) {
        if constexpr (tls) {
            return Stream(std::move(socket), *context);
        } else {
            return Stream(std::move(socket));
        }
    }
    beast::tcp_stream& layer() { return beast::get_lowest_layer(stream_); }
    tcp::socket& socket() { return layer().socket(); }

    // TLS first, within the time a request's header has (a client that connects and never says
    // hello is closed as one that sends no request), and waiting for a header meanwhile: a
    // newcomer at a limit may take its place.
    void handshake() requires tls {
        phase_ = Phase::header;
        header_since_ = std::chrono::steady_clock::now();
        layer().expires_after(std::min(server_.settings.header_timeout, server_.settings.read_timeout));
        stream_.async_handshake(asio::ssl::stream_base::server, [self = this->shared_from_this()](const error_code& error) {
            if (error) return self->close();  // not TLS (plain HTTP), a protocol refused, or too slow
            self->read_request();
        });
    }

    // The read of a header ends now (parking it, on_header); every byte it took is then in
    // buffer_. A read whose bytes had already come but did not complete a header reads on: it is
    // cancelled again until the header is complete (and answered) or the read has ended.
    void stop_reading() {
        error_code ignored;
        socket().cancel(ignored);
        asio::post(server_.loop, [self = this->shared_from_this()] {
            if (!self->closed_ && self->phase_ == Phase::header) self->stop_reading();
        });
    }

    void wait_briefly_for_body() {
        body_grace_.expires_after(hand_over_body_grace);
        body_grace_.async_wait([self = this->shared_from_this()](const error_code& error) {
            if (!error && self->phase_ == Phase::body) self->close();
        });
    }

    // Into the listener for the next server, with what it has read of the next request.
    void park() {
        if (closed_) return;
        if constexpr (tls) return close();
        error_code error;
        const int fd = socket().release(error);
        if (!error) {
            const auto bytes = buffer_.cdata();
            // Between requests (after a response) the parser holds the last one, already answered.
            std::string next = phase_ == Phase::header ? header_so_far(parser_->get()) : std::string();
            next.append(static_cast<const char*>(bytes.data()), bytes.size());
            server_.listener->park(fd, std::move(next));
        }
        close();
    }

    void read_request() {
        phase_ = Phase::header;
        header_since_ = std::chrono::steady_clock::now();
        parser_.emplace();
        limit(*parser_, server_.settings);
        // The header within header_timeout and the whole request within read_timeout, both from
        // here: a client that sends half of one and stalls is closed, as is one that trickles it
        // a byte at a time (which read_timeout alone would let hold its slot for longer).
        layer().expires_after(std::min(server_.settings.header_timeout, server_.settings.read_timeout));
        http::async_read_header(stream_, buffer_, *parser_,
                                [self = this->shared_from_this()](const error_code& error, std::size_t) { self->on_header(error); });
    }

    void on_header(const error_code& error) {
        // Cancelled by stop_reading(): every header read is, when the server hands over.
        if (server_.handing_over && error == asio::error::operation_aborted) return park();
        if (error) return refuse_unreadable(error);
        phase_ = Phase::body;
        layer().expires_at(header_since_ + server_.settings.read_timeout);
        if (server_.handing_over) wait_briefly_for_body();  // a header completed as the stop came
        if (auto refused = framing_refusal(*parser_)) return send(*refused, true);
        const auto& header = parser_->get();
        if (header.payload_size() && *header.payload_size() > server_.settings.body_limit) {
            return send(too_large(server_.settings), true);
        }
        if (beast::iequals(header[http::field::expect], "100-continue")) {
            continue_ = std::make_shared<std::string>("HTTP/1.1 100 Continue\r\n\r\n");
            asio::async_write(stream_, asio::buffer(*continue_), [self = this->shared_from_this()](const error_code& e, std::size_t) {
                if (e) return self->close();
                self->read_body();
            });
            return;
        }
        read_body();
    }

    void read_body() {
        http::async_read(stream_, buffer_, *parser_, [self = this->shared_from_this()](const error_code& error, std::size_t) {
            if (error) return self->refuse_unreadable(error);
            self->dispatch();
        });
    }

    // A request that could not be read: answered where the client can still use an answer.
    void refuse_unreadable(const error_code& error) {
        if (auto refusal = refusal_for(error, server_.settings)) return send(*refusal, true);
        close();
    }

    // RFC 9110, 9.3.2: HEAD is GET without the body (its length still said), which a general
    // purpose server must support; a stream of events has no length, and ends at once.
    void dispatch() {
        phase_ = Phase::answering;
        const auto& message = parser_->get();
        keep_alive_ = message.keep_alive();
        head_ = message.method() == http::verb::head;
        HttpRequest request = to_request(message);
        request.client = client_.to_string();
        if (head_) request.method = "GET";
        HttpOutcome outcome = server_.handler.handle(request);
        if (head_ && outcome.events) {
            HttpResponse stream;
            stream.content_type = "text/event-stream";
            return send(stream, true);
        }
        if (outcome.events) {
            if (auto refusal = server_.over_stream_limits(client_)) return send(*refusal, true);
            return start_events(outcome.events);
        }
        if (outcome.deferred) return run_deferred(outcome.deferred);
        send(outcome.response, false);
    }

    // Started here, answered from whichever thread finishes it; the connection reads nothing
    // meanwhile. The responder's guard keeps the network loop running until the response is
    // back, even when stop() has closed everything else.
    void run_deferred(const std::function<void(HttpResponder)>& start) {
        waiting_for_worker_ = true;
        layer().expires_never();
        auto answered = std::make_shared<std::atomic<bool>>(false);
        auto pending = std::make_shared<Pending>(this->shared_from_this());
        start([pending, answered](HttpResponse response) {
            if (answered->exchange(true)) return;
            asio::post(pending->connection->server_.loop, [self = pending->connection, response = std::move(response)] {
                self->waiting_for_worker_ = false;
                self->send(response, false);
            });
        });
    }

    // What a responder holds while the work it waits for runs on another thread (a line's
    // worker, the history's): the connection, and the loop kept running for its answer. Whatever
    // thread lets the responder go, the connection is let go on the loop, before the loop may
    // end: its timers belong to the loop, which must still be there when they go. It counts as
    // live until it has let go of the loop too, so a stop waits for that: on a loop another runs
    // (the engine's), the loop may be gone as soon as the stop returns.
    struct Pending {
        explicit Pending(std::shared_ptr<Connection> held)
            : server(&held->server_), guard(asio::make_work_guard(held->server_.loop)), connection(std::move(held)) {
            server->count_live(+1);
        }
        ~Pending() {
            asio::post(guard.get_executor(), [released = std::move(connection)] {});
            guard.reset();
            server->count_live(-1);  // the last use of the server here
        }
        Pending(const Pending&) = delete;
        Pending& operator=(const Pending&) = delete;

        HttpServer::State* server;  // there until the stop returns, which waits for this
        asio::executor_work_guard<asio::io_context::executor_type> guard;
        std::shared_ptr<Connection> connection;
    };

    void send(const HttpResponse& response, bool close_after) {
        if (closed_) return;
        phase_ = Phase::writing;
        auto message = std::make_shared<http::response<http::string_body>>(static_cast<http::status>(response.status), 11);
        message->set(http::field::server, "loopwire");
        if constexpr (tls) message->set(http::field::strict_transport_security, hsts);
        message->set(http::field::content_type, response.content_type);
        for (const auto& [name, value] : response.headers) message->set(name, value);
        message->body() = response.body;
        const bool again = keep_alive_ && !close_after && !close_after_response_ && (!server_.stopping || server_.handing_over);
        message->keep_alive(again);
        message->prepare_payload();
        if (std::exchange(head_, false)) {
            const auto length = message->body().size();
            message->body().clear();
            message->content_length(length);
        }
        layer().expires_after(server_.settings.read_timeout);
        http::async_write(stream_, *message, [self = this->shared_from_this(), message, again](const error_code& error, std::size_t) {
            if (error) return self->close();
            if (!again) return self->finish();
            if (!self->server_.stopping) return self->read_request();
            if (self->server_.handing_over) return self->park();
            self->close();
        });
    }

    // After the last response: no more to send, and what the client still sends (the rest of a
    // refused body) is read and dropped for a moment, so that closing does not reset the
    // connection before the client has read the response.
    void finish() {
        phase_ = Phase::finishing;
        if constexpr (tls) {
            // close_notify, so that the client knows the response is whole; its own awaited for
            // a moment.
            layer().expires_after(std::chrono::seconds(1));
            stream_.async_shutdown([self = this->shared_from_this()](const error_code&) { self->close(); });
            return;
        }
        error_code ignored;
        socket().shutdown(tcp::socket::shutdown_send, ignored);
        layer().expires_after(std::chrono::seconds(1));
        drain_ = std::make_shared<std::array<char, 4096>>();
        drain_some(0);
    }

    void drain_some(std::size_t drained) {
        if (drained > server_.settings.body_limit * 4) return close();
        stream_.async_read_some(asio::buffer(*drain_), [self = this->shared_from_this(), drained](const error_code& error, std::size_t n) {
            if (error) return self->close();
            self->drain_some(drained + n);
        });
    }

    // --- server-sent events -------------------------------------------------------------------

    void start_events(const std::function<ValueSubscription(EventSender)>& subscribe) {
        phase_ = Phase::events;
        streaming_ = true;
        ++server_.event_streams;
        ++server_.streams_per_client[client_];
        queue_ = std::make_shared<EventQueue>();
        queue_->pending =
            "HTTP/1.1 200 OK\r\nServer: loopwire\r\nContent-Type: text/event-stream\r\nCache-Control: no-cache\r\n"
            "Connection: close\r\nX-Accel-Buffering: no\r\n";
        if constexpr (tls) queue_->pending += fmt::format("Strict-Transport-Security: {}\r\n", hsts);
        queue_->pending += "\r\n";
        layer().expires_never();
        // A small send buffer: a client that stops reading backs the stream up into a write that
        // waits (and is timed out by send_timeout) after kilobytes, not after megabytes the
        // kernel would otherwise take on its behalf.
        error_code ignored;
        socket().set_option(asio::socket_base::send_buffer_size(event_send_buffer), ignored);
        std::weak_ptr<Connection> weak = this->shared_from_this();
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
        write_events(0);
    }

    // Piece by piece, each given send_timeout: a client that reads, however slowly, stays; one
    // that has taken nothing for send_timeout is dropped (its slot is for someone who reads).
    void write_events(std::size_t from) {
        layer().expires_after(server_.settings.send_timeout);
        stream_.async_write_some(asio::buffer(out_.data() + from, out_.size() - from),
                                 [self = this->shared_from_this(), from](const error_code& error, std::size_t written) {
                                     if (error) {
                                         self->writing_ = false;
                                         return self->close();
                                     }
                                     if (from + written < self->out_.size()) return self->write_events(from + written);
                                     self->writing_ = false;
                                     self->layer().expires_never();
                                     self->flush_events();
                                 });
    }

    // The client sends nothing more on an event stream: a read ends only when it goes.
    void watch_for_close() {
        drain_ = std::make_shared<std::array<char, 4096>>();
        auto on_read = [self = this->shared_from_this()](const error_code& error, std::size_t) {
            if (error) return self->close();
            self->watch_for_close();
        };
        // Plain, on the socket itself: no timeout of the stream's (a write's) ends it. Over TLS
        // through the session, which must see what comes (an alert, close_notify).
        if constexpr (tls) {
            stream_.async_read_some(asio::buffer(*drain_), std::move(on_read));
        } else {
            socket().async_read_some(asio::buffer(*drain_), std::move(on_read));
        }
    }

    void beat() {
        heartbeat_.expires_after(server_.settings.event_heartbeat);
        heartbeat_.async_wait([self = this->shared_from_this()](const error_code& error) {
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
    // Since when it has waited for a request's header, while it does (nullopt otherwise): what
    // makes it one to close for a newcomer at a limit (HttpServer::State::make_room).
    std::optional<std::chrono::steady_clock::time_point> waiting_for_header_since() const override {
        if (closed_ || phase_ != Phase::header) return std::nullopt;
        return header_since_;
    }
    const asio::ip::address& client() const override { return client_; }

    void close() override {
        if (std::exchange(closed_, true)) return;
        subscription_.reset();  // waits for a callback under way on a poll thread; it only queues
        heartbeat_.cancel();
        body_grace_.cancel();
        error_code ignored;
        socket().shutdown(tcp::socket::shutdown_both, ignored);
        layer().close();
        let_go();
    }

private:
    static constexpr int event_send_buffer = 16 * 1024;
    // Browsers that have seen this over HTTPS use HTTPS alone for the host for a year.
    static constexpr const char* hsts = "max-age=31536000";
    static constexpr std::chrono::seconds hand_over_body_grace{1};

    // The connection no longer counts against the limits; once.
    void let_go() {
        if (std::exchange(counted_, false)) {
            server_.connections.erase(this);
            if (--server_.per_client[client_] == 0) server_.per_client.erase(client_);
        }
        if (std::exchange(streaming_, false)) {
            --server_.event_streams;
            if (--server_.streams_per_client[client_] == 0) server_.streams_per_client.erase(client_);
        }
    }

    std::shared_ptr<HttpServer::State> kept_;  // first: goes last
    HttpServer::State& server_;
    asio::ip::address client_;
    TlsContext context_;  // the TLS session's, kept for as long as it lasts; none for plain HTTP
    bool counted_ = true;
    bool streaming_ = false;  // counted as an event stream
    std::chrono::steady_clock::time_point header_since_;  // when the read of the latest header began
    Stream stream_;
    beast::flat_buffer buffer_{read_buffer_limit(server_.settings)};
    std::optional<http::request_parser<http::string_body>> parser_;
    std::shared_ptr<std::string> continue_;
    std::shared_ptr<std::array<char, 4096>> drain_;
    bool keep_alive_ = false;
    bool head_ = false;  // the request being answered is a HEAD
    bool closed_ = false;
    bool waiting_for_worker_ = false;
    bool close_after_response_ = false;
    Phase phase_ = Phase::header;
    // Event streams:
    std::shared_ptr<EventQueue> queue_;
    ValueSubscription subscription_;
    asio::steady_timer heartbeat_;
    asio::steady_timer body_grace_{server_.loop};  // a stop handing over: how long a body may take
    std::string out_;
    bool writing_ = false;
};

void HttpServer::State::accept() {
    acceptor.async_accept(loop, [self = shared_from_this()](const error_code& error, tcp::socket socket) {
        self->on_accept(error, std::move(socket));
    });
}

void HttpServer::State::count_live(int change) {
    std::lock_guard lock(live_mutex);
    live = change > 0 ? live + 1 : live - 1;
    live_changed.notify_all();
}

void HttpServer::State::on_accept(const error_code& error, tcp::socket socket) {
    if (stopping || error == asio::error::operation_aborted) return;
    if (error) {
        // Out of descriptors or memory: accepting again at once would fail just as fast.
        accept_pause.expires_after(std::chrono::milliseconds(100));
        accept_pause.async_wait([self = shared_from_this()](const error_code& e) {
            if (!e && !self->stopping) self->accept();
        });
        return;
    }
    const auto client = client_of(socket);
    if (!settings.allow.allows(client)) {
        // Closed before a byte is read: an address outside the allow list costs nothing more.
        count_not_allowed();
        error_code ignored;
        socket.close(ignored);
        accept();
        return;
    }
    auto refusal = over_limits(client);
    while (refusal && make_room(client, refusal->status == 429)) refusal = over_limits(client);
    if (refusal) {
        refuse(socket, refusal->status, refusal->status == 503 ? "Service Unavailable" : "Too Many Requests", refusal->body);
    } else {
        serve(std::move(socket), client, {});
    }
    accept();
}

// The refusal of one more connection from `client`, if it is one too many.
std::optional<HttpResponse> HttpServer::State::over_limits(const asio::ip::address& client) const {
    if (connections.size() >= settings.max_connections) {
        return error_response(503, fmt::format("too many connections (at most {}); try again later", settings.max_connections));
    }
    const auto from_client = per_client.find(client);
    if (from_client != per_client.end() && from_client->second >= settings.max_connections_per_client) {
        // One address holding this many (a client that opens and stalls, or streams it never
        // reads) must not take the slots everyone else needs.
        return error_response(429, fmt::format("too many connections from {} (at most {} at once from one address); close "
                                               "some first, or raise [http] max_connections_per_client",
                                               client.to_string(), settings.max_connections_per_client));
    }
    return std::nullopt;
}

// An event stream more from `client` than its share of the connections, if it is one.
std::optional<HttpResponse> HttpServer::State::over_stream_limits(const asio::ip::address& client) const {
    HttpResponse refusal;
    if (event_streams >= settings.max_event_streams) {
        refusal = error_response(503, fmt::format("too many event streams (at most {}, so that the other connections are left "
                                                  "for requests); try again later, or raise [http] max_event_streams",
                                                  settings.max_event_streams));
    } else if (const auto from_client = streams_per_client.find(client);
               from_client != streams_per_client.end() && from_client->second >= settings.max_event_streams_per_client) {
        refusal = error_response(429, fmt::format("too many event streams from {} (at most {} at once from one address); "
                                                  "close some dashboards first, or raise [http] max_event_streams_per_client",
                                                  client.to_string(), settings.max_event_streams_per_client));
    } else {
        return std::nullopt;
    }
    refusal.headers.emplace_back("Retry-After", "5");
    return refusal;
}

// Room for a newcomer at a limit: a connection waiting for a request's header is closed. It is
// idle between requests (HTTP lets a server close those), or sends its header too slowly to be
// worth its slot. Refusing instead would let clients that reconnect as soon as header_timeout
// closes them hold every slot. Which one: at its address's limit (`from_client`), the newcomer's
// own; at the server's limit, one of the address that holds the most connections. Of those, the
// one that has waited longest, so that one just connected, whose header may be on its way, goes
// last. By address first: clients that open many connections (a slowloris reconnecting as fast as
// it is closed) take each other's places, not that of a client that has just opened its one.
// None being answered or streaming is closed: false when there is no other.
bool HttpServer::State::make_room(const asio::ip::address& client, bool from_client) {
    std::shared_ptr<ConnectionBase> chosen;
    std::size_t chosen_holds = 0;
    std::chrono::steady_clock::time_point chosen_since;
    for (const auto& [raw, weak] : connections) {
        auto connection = weak.lock();
        if (!connection || (from_client && connection->client() != client)) continue;
        const auto since = connection->waiting_for_header_since();
        if (!since) continue;
        const auto found = per_client.find(connection->client());
        const std::size_t holds = found == per_client.end() ? 0 : found->second;
        if (!chosen || holds > chosen_holds || (holds == chosen_holds && *since < chosen_since)) {
            chosen = std::move(connection);
            chosen_holds = holds;
            chosen_since = *since;
        }
    }
    if (!chosen) return false;
    chosen->close();
    return true;
}

void HttpServer::State::serve(tcp::socket socket, const asio::ip::address& client, std::string_view buffered) {
    auto start = [&](auto connection) {
        connections[connection.get()] = connection;
        connection->start(buffered);
    };
    if (auto context = tls_context()) {
        start(std::make_shared<Connection<TlsStream>>(shared_from_this(), std::move(socket), client, std::move(context)));
    } else {
        start(std::make_shared<Connection<PlainStream>>(shared_from_this(), std::move(socket), client, nullptr));
    }
}

// The keep-alive connections the server before this one parked in the listener (a reload): served
// on as if accepted here. Beyond this server's limits they are closed, unanswered: their clients
// sent nothing yet that an answer would belong to, and reconnect.
void HttpServer::State::adopt(std::vector<HttpListener::Parked> parked) {
    // Handed over by a plain HTTP server: their clients would not speak TLS to this one.
    if (tls_context()) return;  // closed with `parked`
    for (auto& connection : parked) {
        tcp::socket socket(loop);
        error_code error;
        const int fd = connection.release();
        socket.assign(listener->ipv6() ? tcp::v6() : tcp::v4(), fd, error);
        if (error) {
            ::close(fd);
            continue;
        }
        const auto client = client_of(socket);
        // A reload that narrowed `allow` closes the parked connections it no longer lets in.
        if (!settings.allow.allows(client)) {
            count_not_allowed();
            continue;  // closed with `socket`
        }
        if (stopping || over_limits(client)) continue;  // closed with `socket`
        serve(std::move(socket), client, connection.buffered());
    }
}

// Told so in one small write the socket buffer takes at once, then closed. The messages are
// the server's own, with nothing to escape.
void HttpServer::State::refuse(tcp::socket& socket, unsigned status, std::string_view reason, std::string_view body) const {
    error_code ignored;
    if (tls_context()) {
        // A refusal over TLS would cost a handshake, which is what the limit is there to spare.
        socket.close(ignored);
        return;
    }
    const std::string refusal = fmt::format(
        "HTTP/1.1 {} {}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nRetry-After: 1\r\n"
        "Connection: close\r\n\r\n{}", status, reason, body.size(), body);
    socket.non_blocking(true, ignored);
    socket.write_some(asio::buffer(refusal), ignored);
    socket.shutdown(tcp::socket::shutdown_both, ignored);
    socket.close(ignored);
}

void HttpServer::State::shut_down(bool hand_over) {
    stopping = true;
    handing_over = hand_over && listener != nullptr;
    error_code ignored;
    acceptor.close(ignored);
    accept_pause.cancel();
    auto open = connections;  // stop() may erase
    for (auto& [raw, weak] : open) {
        if (auto connection = weak.lock()) connection->stop(handing_over);
    }
    std::lock_guard lock(live_mutex);
    shut = true;
    live_changed.notify_all();
}

HttpServer::HttpServer(std::shared_ptr<State> state) : state_(std::move(state)) {}

HttpServer::~HttpServer() { stop(); }

Result<HttpListener> HttpListener::open(const std::string& host, std::uint16_t port) {
    const bool ipv6 = host.find(':') != std::string::npos;
    const std::string where = fmt::format("http.listen {}{}{}:{}", ipv6 ? "[" : "", host, ipv6 ? "]" : "", port);
    asio::io_context resolving{1};
    error_code error;
    tcp::resolver resolver(resolving);
    auto endpoints = resolver.resolve(host, std::to_string(port), tcp::resolver::passive | tcp::resolver::numeric_service, error);
    if (error || endpoints.empty()) {
        return make_error(ErrorKind::link, fmt::format("{}: cannot resolve the address: {}", where, error.message()));
    }
    const tcp::endpoint endpoint = *endpoints.begin();
    tcp::acceptor acceptor(resolving);
    acceptor.open(endpoint.protocol(), error);
    if (!error) acceptor.set_option(tcp::acceptor::reuse_address(true), error);
    if (!error) acceptor.bind(endpoint, error);
    if (!error) acceptor.listen(asio::socket_base::max_listen_connections, error);
    if (error) {
        return make_error(ErrorKind::link, fmt::format("{}: {}{}", where, error.message(),
                                                       error == asio::error::address_in_use
                                                           ? " (another program listens there: choose another port in [http] listen)"
                                                           : ""));
    }
    const auto bound = acceptor.local_endpoint().port();
    const bool v6 = endpoint.protocol() == tcp::v6();
    return HttpListener(host, port, bound, acceptor.release(), v6);
}

HttpListener::HttpListener(HttpListener&& other) noexcept
    : host_(std::move(other.host_)), asked_port_(other.asked_port_), port_(other.port_),
      fd_(std::exchange(other.fd_, -1)), ipv6_(other.ipv6_), parked_mutex_(std::move(other.parked_mutex_)),
      parked_(std::move(other.parked_)), not_allowed_(std::move(other.not_allowed_)) {}

HttpListener& HttpListener::operator=(HttpListener&& other) noexcept {
    if (this != &other) {
        if (fd_ >= 0) ::close(fd_);
        host_ = std::move(other.host_);
        asked_port_ = other.asked_port_;
        port_ = other.port_;
        fd_ = std::exchange(other.fd_, -1);
        ipv6_ = other.ipv6_;
        parked_mutex_ = std::move(other.parked_mutex_);
        parked_ = std::move(other.parked_);
        not_allowed_ = std::move(other.not_allowed_);
    }
    return *this;
}

HttpListener::~HttpListener() {
    if (fd_ >= 0) ::close(fd_);
}

HttpListener::Parked::~Parked() {
    if (fd_ >= 0) ::close(fd_);
}

void HttpListener::park(int fd, std::string buffered) {
    std::lock_guard lock(*parked_mutex_);
    parked_.emplace_back(fd, std::move(buffered));
}

std::vector<HttpListener::Parked> HttpListener::take_parked() {
    std::lock_guard lock(*parked_mutex_);
    return std::exchange(parked_, {});
}

Result<std::unique_ptr<HttpServer>> HttpServer::open(const HttpServerSettings& settings, HttpHandler& handler,
                                                     boost::asio::io_context* loop, HttpListener* listener) {
    HttpListener* kept = listener;
    std::optional<HttpListener> own;
    if (!listener) {
        auto opened = HttpListener::open(settings.host, settings.port);
        if (!opened) return opened.error();
        own.emplace(std::move(*opened));
        listener = &*own;
    }
    auto state = std::make_shared<State>(settings, handler, loop, kept);
    if (!settings.certificate.empty()) {
        auto context = load_tls(settings.certificate, settings.private_key);
        if (!context) return make_error(ErrorKind::usage, fmt::format("http: {}", context.error().message));
        state->tls = std::move(*context);
    }
    // The server accepts on a descriptor of its own: closing it when the server stops leaves the
    // listener (a kept one) listening.
    const int fd = ::fcntl(listener->fd(), F_DUPFD_CLOEXEC, 0);
    error_code error;
    if (fd >= 0) state->acceptor.assign(listener->ipv6() ? tcp::v6() : tcp::v4(), fd, error);
    if (fd < 0 || error) {
        if (fd >= 0) ::close(fd);
        return make_error(ErrorKind::link, fmt::format("http.listen port {}: cannot accept on the listening socket: {}",
                                                       listener->port(), fd < 0 ? std::strerror(errno) : error.message()));
    }
    state->port = listener->port();
    // Started on the loop's thread, which owns the acceptor from here on.
    asio::post(state->loop, [s = state, parked = kept ? kept->take_parked() : std::vector<HttpListener::Parked>{}]() mutable {
        s->adopt(std::move(parked));
        s->accept();
    });
    if (state->own_loop) {
        state->thread = std::thread([s = state.get()] { s->loop.run(); });
        name_thread(state->thread.native_handle(), "lw-http");
    }
    return std::unique_ptr<HttpServer>(new HttpServer(std::move(state)));
}

std::uint64_t HttpServer::not_allowed() const {
    return state_->listener ? state_->listener->not_allowed() : state_->not_allowed.load(std::memory_order_relaxed);
}

std::uint16_t HttpServer::port() const { return state_->port; }

Result<void> HttpServer::reload_certificate() {
    const auto& settings = state_->settings;
    if (settings.certificate.empty()) return {};
    auto context = load_tls(settings.certificate, settings.private_key);
    if (!context) return context.error();
    std::lock_guard lock(state_->tls_mutex);
    state_->tls = std::move(*context);
    return {};
}

void HttpServer::stop(bool hand_over) {
    std::call_once(state_->stopped, [this, hand_over] {
        asio::post(state_->loop, [s = state_, hand_over] { s->shut_down(hand_over); });
        // Returns once every connection is closed and every responder has let go: the deferred
        // work under way has answered.
        {
            std::unique_lock lock(state_->live_mutex);
            state_->live_changed.wait(lock, [s = state_.get()] { return s->shut && s->live == 0; });
        }
        if (state_->own_loop) state_->thread.join();
    });
}

}  // namespace loopwire::gateway

namespace loopwire::gateway {

ParsedHttpRequest parse_http_request(std::string_view bytes, const HttpServerSettings& settings) {
    RequestParser parser;
    limit(parser, settings);
    parser.eager(true);
    error_code error;
    while (!bytes.empty() && !parser.is_done()) {
        const std::size_t used = parser.put(asio::buffer(bytes.data(), bytes.size()), error);
        if (error && error != http::error::need_more) return {std::nullopt, refusal_for(error, settings)};
        if (used == 0) return {};  // the parser wants more than there is
        bytes.remove_prefix(used);
        error = {};
    }
    if (!parser.is_done()) return {};
    if (auto refused = framing_refusal(parser)) return {std::nullopt, refused};
    // As the connection checks before it reads a body.
    if (parser.content_length() && *parser.content_length() > settings.body_limit) return {std::nullopt, too_large(settings)};
    return {to_request(parser.get()), std::nullopt};
}

}  // namespace loopwire::gateway
