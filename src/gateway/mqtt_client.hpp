#pragma once
// What the gateway's two MQTT clients (the MQTT front, gateway/mqtt_bridge.hpp, and the Sparkplug
// B edge node, gateway/sparkplug/sparkplug_node.hpp) share about driving libmosquitto from a
// thread of their own: the library's start, a wake-up for that thread's poll(), TLS and
// credentials, and one turn of the network loop.
#include <chrono>
#include <functional>
#include <optional>
#include <stop_token>
#include <string>

#include "gateway/gateway_config.hpp"

struct mosquitto;

namespace loopwire::gateway::mqtt {

// mosquitto_lib_init, once per process; never cleaned up (other clients may still use it).
void init_library_once();

// Wakes the network thread's poll() from another thread: an eventfd, readable once notified
// until drained.
class Wakeup {
public:
    Wakeup();
    ~Wakeup();
    Wakeup(const Wakeup&) = delete;
    Wakeup& operator=(const Wakeup&) = delete;

    int fd() const { return fd_; }
    void notify() const;
    void drain() const;

private:
    int fd_;
};

// The broker's TLS files and the credentials. The files were checked when the configuration was
// read; a failure here (a certificate libmosquitto cannot use) is told through `say` and the
// client keeps trying, as with a broker that cannot be reached.
void configure_security(mosquitto* client, const std::optional<MqttTls>& tls, const std::string& username,
                        const std::string& password, const std::function<void(const std::string&)>& say);

// A value goes out as soon as it is published: Nagle's algorithm off (libmosquitto leaves it on),
// or a burst of small messages waits on the broker's delayed acknowledgement (up to 40 ms on
// Linux; bench/mqtt_throughput.sh measured, at 500 parameters, p99 49-54 ms with it and 18-25 ms
// without). TCP_CORK around a batch, tried as well, did not help: mosquitto reads each packet
// with reads of its own whatever the segments.
void send_without_delay(mosquitto* client);

// One turn of the network loop on libmosquitto's external-loop interface: waits up to `idle`
// for the socket or the wake-up, then reads, writes and does the keep-alive work. Returns
// libmosquitto's code (MOSQ_ERR_SUCCESS, or why the connection is gone). mosquitto_loop()
// would wait out its whole timeout with a publication queued: the poll-to-subscriber latency.
int turn(mosquitto* client, const Wakeup& wakeup, std::chrono::milliseconds idle);

// Sleeps `delay`, or less when stopped.
void pause(const std::stop_token& stop, std::chrono::milliseconds delay);

// Why mosquitto_connect failed, in words (errno's text for a socket error).
std::string connect_failure(int rc);

// A connection that ended before the broker acknowledged it (`rc`, from the network loop): the
// port answered TCP but not MQTT, or the broker dropped the handshake. Without this a peer that
// sends garbage was retried every few seconds with nothing in the log.
std::string handshake_failure(int rc);

}  // namespace loopwire::gateway::mqtt
