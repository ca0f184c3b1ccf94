#pragma once
// What the gateway's two MQTT clients (the MQTT front, gateway/mqtt_bridge.hpp, and the Sparkplug
// B edge node, gateway/sparkplug/sparkplug_node.hpp) share about libmosquitto besides its driver
// on the engine's loop (gateway/mqtt_loop_driver.hpp): the library's start, TLS and credentials,
// and what a failure is called.
#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "gateway/gateway_config.hpp"

struct mosquitto;

namespace loopwire::gateway::mqtt {

// mosquitto_lib_init, once per process; never cleaned up (other clients may still use it).
void init_library_once();

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

// Why a command (the MQTT front's .../set, a Sparkplug NCMD or DCMD) that arrives with the retain
// flag is refused, for its answer and the log: the broker keeps a retained message and hands it to
// every new subscription, so it would be written again at each reconnection, over whatever was
// written since. Both fronts take commands live only.
std::string retained_command_refusal(std::string_view topic);

// A connection that ended before the broker acknowledged it (`why`, in words, from the driver):
// the port answered TCP but not MQTT, or the broker dropped the handshake. Without this a peer
// that sends garbage was retried every few seconds with nothing in the log.
std::string handshake_failure(const std::string& why);

}  // namespace loopwire::gateway::mqtt
