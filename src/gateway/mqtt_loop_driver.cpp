#include "gateway/mqtt_loop_driver.hpp"

#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <cstdint>
#include <future>
#include <optional>
#include <thread>
#include <utility>

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/address.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/posix/stream_descriptor.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <mosquitto.h>

#include "common/thread_name.hpp"

namespace loopwire::gateway::mqtt {
namespace {

namespace asio = boost::asio;
using boost::system::error_code;

// How often the keep-alive work runs (mosquitto_loop_misc: PINGREQ, the broker's silence) when
// nothing else happens on the connection.
constexpr std::chrono::milliseconds misc_every{500};

bool numeric_address(const std::string& host) {
    error_code error;
    (void)asio::ip::make_address(host, error);
    return !error;
}

}  // namespace

// Shared with the handlers waiting on the loop, which may run after the driver has gone (a
// cancelled wait completes later); they do nothing once `stopped`. Everything but `wake_posted`
// is the loop's.
struct LoopDriver::Core : std::enable_shared_from_this<LoopDriver::Core> {
    Core(asio::io_context& l, mosquitto* c, std::string h, std::chrono::milliseconds f, std::chrono::milliseconds la, Hooks k)
        : loop(l), client(c), host(std::move(h)), first(f), last(la), delay(f), hooks(std::move(k)) {}

    asio::io_context& loop;
    mosquitto* client;
    const std::string host;
    const std::chrono::milliseconds first;
    const std::chrono::milliseconds last;
    std::chrono::milliseconds delay;
    Hooks hooks;
    asio::steady_timer retry{loop};
    asio::steady_timer misc{loop};
    asio::ip::tcp::resolver resolver{loop};
    // The client's socket, watched, never closed here: libmosquitto owns it.
    std::optional<asio::posix::stream_descriptor> socket;
    std::uint64_t generation = 0;  // of `socket`: waits of a socket since forgotten do nothing
    bool reading = false;
    bool writing = false;
    bool misc_set = false;
    bool connecting = false;  // the TCP connection started, not yet made
    bool stopped = false;
    std::atomic<bool> wake_posted{false};

    void attempt() {
        if (stopped) return;
        if (numeric_address(host)) return connect_now();
        resolver.async_resolve(host, "", [self = shared_from_this()](const error_code& error, const auto&) {
            if (self->stopped || error == asio::error::operation_aborted) return;
            if (error) {
                self->hooks.unreachable("cannot resolve " + self->host + ": " + error.message());
                return self->back_off();
            }
            self->connect_now();
        });
    }

    void connect_now() {
        const int rc = hooks.connect();
        if (rc != MOSQ_ERR_SUCCESS) {
            hooks.unreachable(rc == MOSQ_ERR_ERRNO ? std::string(std::strerror(errno)) : std::string(mosquitto_strerror(rc)));
            return back_off();
        }
        connecting = true;
        watch();
    }

    // The TCP connection, started without waiting, is made or has failed once the socket is
    // writable: a failure is the broker not reached, as a blocking connect would have said.
    bool connection_failed() {
        connecting = false;
        int failure = 0;
        socklen_t size = sizeof failure;
        if (::getsockopt(mosquitto_socket(client), SOL_SOCKET, SO_ERROR, &failure, &size) != 0) failure = errno;
        if (failure == 0) return false;
        forget();
        hooks.unreachable(std::strerror(failure));
        back_off();
        return true;
    }

    // (Re)arms the waits on the client's socket: readable always, writable while libmosquitto
    // has something to write, and the keep-alive work.
    void watch() {
        const int fd = mosquitto_socket(client);
        if (fd < 0) return end(mosquitto_strerror(MOSQ_ERR_NO_CONN));
        if (!socket || socket->native_handle() != fd) {
            forget();
            socket.emplace(loop, fd);
        }
        const auto current = generation;
        if (!reading && !connecting) {
            reading = true;
            socket->async_wait(asio::posix::stream_descriptor::wait_read, [self = shared_from_this(), current](const error_code& error) {
                if (current != self->generation) return;
                self->reading = false;
                if (!error) self->turn(true);
            });
        }
        if (!writing && (connecting || mosquitto_want_write(client))) {
            writing = true;
            socket->async_wait(asio::posix::stream_descriptor::wait_write, [self = shared_from_this(), current](const error_code& error) {
                if (current != self->generation) return;
                self->writing = false;
                if (error || self->stopped) return;
                if (self->connecting && self->connection_failed()) return;
                self->turn(false);
            });
        }
        if (!misc_set) {
            misc_set = true;
            misc.expires_after(misc_every);
            misc.async_wait([self = shared_from_this(), current](const error_code& error) {
                if (current != self->generation) return;
                self->misc_set = false;
                if (!error) self->turn(false);
            });
        }
    }

    // One turn of libmosquitto's network work, then the client's own.
    void turn(bool readable) {
        if (stopped) return;
        // Until the TCP connection is made, only its writability tells (above).
        if (connecting) return watch();
        int rc = MOSQ_ERR_SUCCESS;
        if (readable) rc = mosquitto_loop_read(client, 1);
        if (rc == MOSQ_ERR_SUCCESS && mosquitto_socket(client) >= 0 && mosquitto_want_write(client)) {
            rc = mosquitto_loop_write(client, 1);
        }
        if (rc == MOSQ_ERR_SUCCESS) rc = mosquitto_loop_misc(client);
        // In words now: the client's own work below makes system calls of its own.
        std::string why;
        if (rc != MOSQ_ERR_SUCCESS) why = rc == MOSQ_ERR_ERRNO ? std::string(std::strerror(errno)) : std::string(mosquitto_strerror(rc));
        if (hooks.turned()) delay = first;
        if (rc != MOSQ_ERR_SUCCESS) return end(why);
        watch();
    }

    void woken() {
        wake_posted = false;
        if (stopped) return;
        if (socket) return connecting ? watch() : turn(false);
        (void)hooks.turned();  // no connection: the client keeps its picture current
    }

    void end(const std::string& why) {
        forget();
        hooks.lost(why);
        back_off();
    }

    void back_off() {
        retry.expires_after(delay);
        delay = std::min(delay * 2, last);
        retry.async_wait([self = shared_from_this()](const error_code& error) {
            if (!error && !self->stopped) self->attempt();
        });
    }

    // Stops watching the socket (its waits complete cancelled, and do nothing).
    void forget() {
        ++generation;
        reading = writing = misc_set = connecting = false;
        misc.cancel();
        if (!socket) return;
        error_code ignored;
        socket->cancel(ignored);
        (void)socket->release();
        socket.reset();
    }
};

struct LoopDriver::OwnLoop {
    asio::io_context loop{1};
    asio::executor_work_guard<asio::io_context::executor_type> busy{loop.get_executor()};
    std::thread thread;
};

LoopDriver::LoopDriver(asio::io_context* loop, const char* thread_name, mosquitto* client, std::string host,
                       std::chrono::milliseconds first, std::chrono::milliseconds last, Hooks hooks) {
    if (!loop) {
        own_ = std::make_unique<OwnLoop>();
        own_->thread = std::thread([own = own_.get()] { own->loop.run(); });
        name_thread(own_->thread.native_handle(), thread_name);
        loop = &own_->loop;
    }
    core_ = std::make_shared<Core>(*loop, client, std::move(host), first, last, std::move(hooks));
}

LoopDriver::~LoopDriver() { stop(); }

void LoopDriver::start() {
    asio::post(core_->loop, [core = core_] { core->attempt(); });
}

void LoopDriver::resume() {
    asio::post(core_->loop, [core = core_] {
        if (mosquitto_socket(core->client) >= 0) return core->watch();
        core->attempt();
    });
}

void LoopDriver::wake() {
    if (core_->wake_posted.exchange(true)) return;
    asio::post(core_->loop, [core = core_] { core->woken(); });
}

void LoopDriver::stop() {
    if (stop_asked_.exchange(true)) return;
    std::promise<void> done;
    asio::post(core_->loop, [core = core_, &done] {
        core->stopped = true;
        core->retry.cancel();
        core->resolver.cancel();
        core->forget();
        done.set_value();
    });
    done.get_future().wait();
    if (!own_) return;
    own_->busy.reset();
    own_->thread.join();  // the cancelled waits complete, and the loop runs out of work
}

}  // namespace loopwire::gateway::mqtt
