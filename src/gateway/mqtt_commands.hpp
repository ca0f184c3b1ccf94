#pragma once
// The writes the MQTT front takes (gateway/mqtt_bridge.hpp): a message on
// PREFIX/DEVICE/PARAMETER/set becomes a write through the gateway's DeviceWriter, and its
// outcome a document on .../set/result. Kept apart from the network code so that the whole
// path from a topic and payload to the answer runs without a broker (tests, fuzz/).
//
// Whatever a publisher sends, the gateway stays up and bounded: a payload longer than
// [mqtt] max_payload is refused unread, at most `max_commands` writes are under way at once
// (more are refused "busy"), and the payload reaches the log quoted and cut and the result
// document as valid JSON (common/peer_text.hpp).
//
// Threads: take() runs where the bridge's network runs (the engine's loop) and never blocks: the write is handed to
// the device's line (DeviceWriter::write_async) and its result is published from the
// completion, on the thread of the line's reply. A slow or dead line delays only its own writes.
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

#include "gateway/device_writer.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/gateway_config.hpp"

namespace loopwire::gateway {

// PREFIX/DEVICE/PARAMETER/set taken apart; none for any other topic.
struct CommandTopic {
    std::string device;
    std::string parameter;
};
std::optional<CommandTopic> command_topic(std::string_view prefix, std::string_view topic);

class MqttCommands {
public:
    // Publishes a set/result document (QoS 1, not retained); must only queue.
    using Publish = std::function<void(std::string topic, std::string payload)>;

    static constexpr std::size_t default_max_commands = 256;

    // A write to a device its polls find silent is refused at once by the writer's policy
    // (silent_device_refusal), in the words every front gives.
    MqttCommands(const MqttConfig& config, const DeviceWriter& writer, Publish publish, GatewayLog log,
                 std::size_t max_commands = default_max_commands);
    // close(), if not done yet.
    ~MqttCommands();
    MqttCommands(const MqttCommands&) = delete;
    MqttCommands& operator=(const MqttCommands&) = delete;

    // One live command from the broker (not retained, not a redelivery): answered on
    // .../set/result, at once when it is refused, else once the line has answered. Topics that
    // are not PREFIX/DEVICE/PARAMETER/set are ignored.
    void take(std::string_view topic, std::string_view payload);

    // A command that came with the retain flag (the copy the broker keeps, handed over at each
    // subscription): never written, its refusal answered on .../set/result and logged.
    void refuse_retained(std::string_view topic, std::string_view payload);

    // Writes handed to the lines and not yet answered.
    std::size_t under_way() const;

    // Takes no more writes (take() still answers refusals), then waits until the writes under
    // way have published their results: each is bounded by the writer's write limit. The
    // publisher must keep sending meanwhile.
    void close();

private:
    void answer(const CommandTopic& command, std::string_view payload, const std::string& error);
    // Counts the write in, or says why it cannot go now (closed, or too many under way).
    std::optional<std::string> admit();
    void finished();

    std::string prefix_;
    bool writes_;
    std::size_t max_payload_;
    std::size_t max_commands_;
    const DeviceWriter& writer_;
    Publish publish_;
    GatewayLog log_;
    mutable std::mutex mutex_;
    std::condition_variable all_answered_;
    std::size_t under_way_ = 0;
    bool closed_ = false;
};

}  // namespace loopwire::gateway
