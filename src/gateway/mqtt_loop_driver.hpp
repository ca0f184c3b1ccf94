#pragma once
// One libmosquitto client driven on an Asio loop through the library's external-loop interface
// (mosquitto_socket, mosquitto_loop_read / _write / _misc), with no thread of its own: the
// gateway's MQTT front runs so on the engine's loop, with the polls whose values it publishes
// (one executor; the thread count does not grow with the fronts).
//
// It connects without blocking the loop (mosquitto_connect_async: the TCP connection and the TLS
// handshake go on in the loop's turns) and, for a broker named by host name, only once an
// asynchronous lookup of the name has succeeded, so that a resolver that does not answer holds up
// no poll (libmosquitto looks the name up again, now answered from the resolver's cache at once).
// A connection that fails or ends is tried again after a back-off, doubling from `first` to
// `last`.
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>

struct mosquitto;

namespace boost::asio {
class io_context;
}

namespace loopwire::gateway::mqtt {

class LoopDriver {
public:
    // All called on the loop.
    struct Hooks {
        // Starts a connection now: mosquitto_connect_async's code.
        std::function<int()> connect;
        // The broker was not reached (the TCP connection failed, the name did not resolve), why
        // in words; the back-off follows.
        std::function<void(const std::string& why)> unreachable;
        // After each turn of the network work, and when woken without a connection: the client's
        // own work (a new connection announced, what was queued sent, values republished).
        // Returns whether a connection was accepted in this turn, which resets the back-off.
        std::function<bool()> turned;
        // The connection, once made, ended (before the broker accepted it, or after), why in
        // words; the back-off follows.
        std::function<void(const std::string& why)> lost;
    };

    // On `loop`, run by its owner for as long as the driver exists (the gateway's engine), or,
    // when none is given, on a loop and a thread of its own named `thread_name` (a benchmark's
    // or a test's client).
    LoopDriver(boost::asio::io_context* loop, const char* thread_name, mosquitto* client, std::string host,
               std::chrono::milliseconds first, std::chrono::milliseconds last, Hooks hooks);
    ~LoopDriver();  // stop()
    LoopDriver(const LoopDriver&) = delete;
    LoopDriver& operator=(const LoopDriver&) = delete;

    void start();  // the first connection attempt, on the loop; from any thread
    // Instead of start(), for a client whose connection another driver made and let go (stop):
    // watches that connection as it is, or connects when it has none; from any thread.
    void resume();
    // A turn soon, on the loop (something was queued to send); from any thread, as often as
    // wanted: one turn for all the calls before it runs.
    void wake();
    // Never on the loop's thread, which must be running: returns once the loop no longer touches
    // the client (the caller may then drive it itself, mosquitto_loop, for a goodbye). Idempotent.
    void stop();

private:
    struct Core;
    struct OwnLoop;
    std::unique_ptr<OwnLoop> own_;  // first: goes after the core's last use
    std::shared_ptr<Core> core_;
    std::atomic<bool> stop_asked_{false};
};

}  // namespace loopwire::gateway::mqtt
