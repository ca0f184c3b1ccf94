#pragma once
// The gateway's MQTT front (docs/DESIGN.md, gateway): publishes what the polls read to a broker,
// retained, and takes writes from it.
//
// Topics (PREFIX from [mqtt] prefix; DEVICE and PARAMETER are configured names, which the
// configuration restricts to [A-Za-z0-9_-], so they are single topic levels that never need
// escaping and never hold a wildcard):
//   PREFIX/status                      "online"; "offline" on a clean stop and as the last will
//   PREFIX/DEVICE/status               the device's status word: "ok", "partial", "no-reply",
//                                      "line-down", "stale", "wrong-device" (client/device_status.hpp)
//   PREFIX/DEVICE/availability         "online" while it answers (ok, partial), else "offline":
//                                      what Home Assistant's availability reads
//   PREFIX/DEVICE/PARAMETER            the value in engineering units, or its status when none
//   PREFIX/DEVICE/PARAMETER/meta       JSON: unit, decimals, writable, min, max, enum labels,
//                                      mnemonic, status, error, last_error (mqtt_documents.hpp)
//   PREFIX/DEVICE/PARAMETER/set        subscribed (QoS 1): a value to write; the retained copy a
//                                      subscription brings is refused on set/result, never
//                                      written (one published retained while the gateway
//                                      listens comes as an ordinary message, MQTT 3.1.1,
//                                      3.3.1.3), and redeliveries of one already taken are ignored
//   PREFIX/DEVICE/PARAMETER/set/result {"ok":true,"value":"..."} or {"ok":false,"error":"..."}
//   DISCOVERY/COMPONENT/ID/config      with discovery = "homeassistant": Home Assistant's documents
// All but set/result are retained. Values go out when they change and again every `republish`.
// The sweep: at its first connection the bridge subscribes for a moment to its own retained
// topics (every DISCOVERY/+/+/config document whose availability or state is PREFIX/status, and
// PREFIX/+/+, PREFIX/+/+/meta), and clears, with an empty retained message, every one the
// configuration no longer publishes: a device or parameter removed (at start or on a reload)
// leaves no entity in Home Assistant and no retained value, status or availability behind. The
// collection never blocks the loop: it ends on a turn after MqttTiming::sweep_window.
// On a clean stop every PREFIX/DEVICE/availability and PREFIX/status say "offline", and every
// PREFIX/DEVICE/status "waiting" (on a reload, only what the next configuration no longer
// publishes: hand_over); a write to a device whose polls find it silent is refused at once by
// the writer's policy (gateway/device_writer.hpp).
//
// Threads: none of its own in the gateway. The libmosquitto client is driven on the engine's loop
// (gateway/mqtt_loop_driver.hpp), with the polls: it connects and reconnects with back-off
// without blocking the loop, publishes what was queued, and republishes every retained topic
// whenever a connection is made (the broker may have lost them). The value stream's callback
// only queues. Writes are handed to their device's line (gateway/mqtt_commands.hpp) and their
// results published when the line has answered, so a slow line holds up neither the loop nor a
// write to another line. A payload over [mqtt] max_payload is refused unread, and at most a
// bounded number of writes wait at once: whatever is published, memory stays bounded.
#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "gateway/device_writer.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/gateway_config.hpp"
#include "gateway/value_cache.hpp"

namespace boost::asio {
class io_context;
}

namespace loopwire::gateway {

struct MqttTiming {
    // Waits between attempts to reach the broker: doubling from the first to the last.
    std::chrono::milliseconds reconnect_first{500};
    std::chrono::milliseconds reconnect_last{10000};
    // How long after its subscriptions are acknowledged the bridge collects what it finds
    // retained of its own (the sweep, below): the broker sends the retained messages right after
    // the SUBACK, so this is a margin for a loaded machine, not a guess at a size.
    std::chrono::milliseconds sweep_window{1500};
};

// The parameters each device publishes (its poll list), by configured device name: what the
// sweep keeps. A device missing here keeps every parameter of its profile.
using PublishedParameters = std::map<std::string, std::set<std::string>>;

class MqttBridge {
public:
    // Starts at once and never fails for want of a broker: it keeps trying in the background
    // (logging each failure once until it connects), while the gateway's lines work on.
    // Subscribes to `cache` for the values and writes through `writer` (its devices are the
    // ones the bridge knows); both must outlive the bridge. The network runs on `loop` (run by
    // its owner for as long as the bridge exists: the gateway's engine), or on a thread of its own
    // when none is given.
    MqttBridge(MqttConfig config, const DeviceWriter& writer, ValueCache& cache, GatewayLog log, MqttTiming timing = {},
               boost::asio::io_context* loop = nullptr, PublishedParameters published = {});
    // Publishes PREFIX/status "offline" and disconnects cleanly, on the caller's thread (never the
    // loop's) once the loop has let the client go.
    ~MqttBridge();
    MqttBridge(const MqttBridge&) = delete;
    MqttBridge& operator=(const MqttBridge&) = delete;

    // Whether the bridge is connected to the broker now.
    bool connected() const;

    // Before the bridge is closed for a reload to `next` (the next configuration's [mqtt], and
    // the names of its devices): what the next bridge publishes again under the same broker and
    // prefix keeps its retained status, so that a reload does not flap the gateway and its
    // devices offline and online; the rest is said "offline" as on a stop.
    void hand_over(const std::optional<MqttConfig>& next, const std::set<std::string>& next_devices);

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace loopwire::gateway
