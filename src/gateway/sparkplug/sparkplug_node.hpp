#pragma once
// The gateway as a Sparkplug B edge node (Eclipse Sparkplug 3.0), so that a SCADA host
// application (Ignition, ...) finds every device and parameter from the births, with no hand
// mapping of topics (docs/DESIGN.md, gateway).
//
// Topics (GROUP, EDGE from [sparkplug]; DEVICE the configured names):
//   spBv1.0/GROUP/NBIRTH/EDGE          on each connection and rebirth: bdSeq, Node Control/Rebirth,
//                                      each line's figures (Lines/LINE/...), seq 0
//   spBv1.0/GROUP/NDATA/EDGE           the lines' figures that changed, every `node_data_every`
//   spBv1.0/GROUP/NDEATH/EDGE          the MQTT will, with that connection's bdSeq (each session
//                                      that reached the broker has the next); also sent on a clean
//                                      stop and when the primary host goes offline
//   spBv1.0/GROUP/NCMD/EDGE            subscribed: Node Control/Rebirth = true births everything again
//   spBv1.0/GROUP/DBIRTH/EDGE/DEVICE   once the device answers: every polled parameter as a metric
//                                      (sparkplug_payloads.hpp), Device Control/Last Error
//   spBv1.0/GROUP/DDATA/EDGE/DEVICE    what changed, by alias; a missing or stale value is null
//   spBv1.0/GROUP/DDEATH/EDGE/DEVICE   when its polls get no answer (or its line is down)
//   spBv1.0/GROUP/DCMD/EDGE/DEVICE     subscribed: writes, checked as `loopwire write` checks them;
//                                      a refusal is told in Device Control/Last Error
//   spBv1.0/STATE/HOST                 with primary_host: births wait for {"online": true}; a
//                                      STATE older than the last taken is ignored
// With store_and_forward, the DDATA the node would have sent while it was not born (the broker
// away, the primary host offline) is kept, bounded by age and count, and sent after the next
// births in its order, each metric with is_historical and its own timestamp. With a history file
// it is kept there too (sparkplug_pending.hpp): what a stopped gateway had not forwarded is
// forwarded by the next run, after each device's birth.
// A reload that leaves [sparkplug] as it is keeps the session (release, take_over).
// An NCMD or DCMD published with the retain flag is refused unread (MQTT 5, "retain as
// published": live or as the broker's retained copy at each subscription), so that an old
// command is never written again at a reconnection.
// Aliases are numbered once, from the configuration (node metrics, then each device's metrics
// in order), so they are the same across rebirths and restarts of the same configuration.
//
// Threads: none of its own in the gateway. The value stream's callback only notes which device
// changed and wakes the network, which runs on the engine's loop (gateway/mqtt_loop_driver.hpp)
// and owns the libmosquitto client and every Sparkplug state (born or not, seq, bdSeq, what was
// last sent), so the messages' order is the order they are made in. Writes are handed to the
// device's line (DeviceWriter) and their outcome comes back through the same wake-up: a slow line
// never holds up the loop. Leaving for a primary host gone offline waits for the NDEATH's
// acknowledgement (2 s at most) in the loop's turns, not by holding it.
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gateway/device_writer.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/gateway_config.hpp"
#include "gateway/sparkplug/sparkplug_pending.hpp"
#include "gateway/value_cache.hpp"

namespace boost::asio {
class io_context;
}

namespace loopwire::gateway {

// A device of the node: its configured name and the parameters its polls read.
struct SparkplugDevice {
    std::string name;
    std::vector<const device::Parameter*> parameters;
};

// A line's figures, for the node's metrics.
struct SparkplugLineFigures {
    std::string name;
    std::uint64_t requests = 0;
    std::uint64_t answered = 0;
    std::uint64_t timeouts = 0;
    bool open = true;
};
using SparkplugLines = std::function<std::vector<SparkplugLineFigures>()>;

struct SparkplugTiming {
    std::chrono::milliseconds reconnect_first{500};
    std::chrono::milliseconds reconnect_last{10000};
    std::chrono::milliseconds node_data_every{10000};  // how often the lines' figures are looked at
    // Store and forward: the most values kept while the node is not born (the oldest dropped).
    std::size_t max_stored = 100000;
};

class SparkplugNode {
public:
    // Starts at once and never fails for want of a broker: it keeps trying in the background.
    // `cache`, `writer` and whatever `lines` reads must outlive the node.
    // The network runs on `loop` (run by its owner for as long as the node exists: the gateway's
    // engine, gateway/mqtt_loop_driver.hpp), or on a thread of its own when none is given.
    SparkplugNode(SparkplugConfig config, std::vector<SparkplugDevice> devices, const DeviceWriter& writer,
                  ValueCache& cache, SparkplugLines lines, GatewayLog log, SparkplugTiming timing = {},
                  boost::asio::io_context* loop = nullptr, SparkplugPending pending = {});
    // Publishes NDEATH and disconnects cleanly, on the caller's thread (never the loop's) once
    // the loop has let the client go.
    ~SparkplugNode();
    SparkplugNode(const SparkplugNode&) = delete;
    SparkplugNode& operator=(const SparkplugNode&) = delete;

    bool connected() const;
    // The values store and forward holds now, to send once the node is born again.
    std::size_t stored() const;

    // For a reload that leaves [sparkplug] as it is (Gateway::hand_over_to): lets go of the
    // gateway's loop, cache, writer and lines, keeping the MQTT connection and every Sparkplug
    // state (bdSeq, seq, what each device was told, what is stored to forward), so that
    // take_over() carries on the same session: no NDEATH, no NBIRTH. False when there is no
    // session to carry on (a connection half made, or the node leaving for a primary host gone
    // offline): then it is destroyed as on a stop. Not on the loop's thread, which must run.
    bool release();
    // After release(), the next gateway's: a device added, or whose metrics changed, is born
    // (DBIRTH) once its polls tell of it, one gone dies (DDEATH), the others carry on without a
    // word; lines added or gone change the node's metrics, and the node is born again (NBIRTH,
    // the same bdSeq, as on a Rebirth command).
    // `pending`: the next gateway's history file, if it has one (its `loaded` is not read: the
    // store carries on in memory).
    void take_over(std::vector<SparkplugDevice> devices, const DeviceWriter& writer, ValueCache& cache,
                   SparkplugLines lines, GatewayLog log, boost::asio::io_context* loop, SparkplugPending pending = {});

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace loopwire::gateway
