#include "gateway/mqtt_commands.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "common/peer_text.hpp"
#include "gateway/mqtt_client.hpp"

namespace loopwire::gateway {

std::optional<CommandTopic> command_topic(std::string_view prefix, std::string_view topic) {
    if (topic.size() <= prefix.size() + 1 || topic.substr(0, prefix.size()) != prefix || topic[prefix.size()] != '/') {
        return std::nullopt;
    }
    const std::string_view rest = topic.substr(prefix.size() + 1);  // DEVICE/PARAMETER/set
    const auto first = rest.find('/');
    if (first == std::string_view::npos) return std::nullopt;
    const auto second = rest.find('/', first + 1);
    if (second == std::string_view::npos || rest.substr(second) != "/set") return std::nullopt;
    CommandTopic command{std::string(rest.substr(0, first)), std::string(rest.substr(first + 1, second - first - 1))};
    if (command.device.empty() || command.parameter.empty()) return std::nullopt;
    return command;
}

MqttCommands::MqttCommands(const MqttConfig& config, const DeviceWriter& writer, Publish publish, GatewayLog log,
                           std::size_t max_commands)
    : prefix_(config.prefix),
      writes_(config.writes),
      max_payload_(config.max_payload),
      max_commands_(max_commands),
      writer_(writer),
      publish_(std::move(publish)),
      log_(std::move(log)) {}

MqttCommands::~MqttCommands() { close(); }

void MqttCommands::close() {
    std::unique_lock lock(mutex_);
    closed_ = true;
    all_answered_.wait(lock, [this] { return under_way_ == 0; });
}

std::size_t MqttCommands::under_way() const {
    std::lock_guard lock(mutex_);
    return under_way_;
}

namespace {

// MQTT tells no publisher's identity: a write came through the broker.
const WriteOrigin from_broker{"mqtt", "broker", {}};

}  // namespace

void MqttCommands::take(std::string_view topic, std::string_view payload) {
    auto command = command_topic(prefix_, topic);
    if (!command) return;
    // Each refusal here, before the writer has the write, is audited as the writer audits its own.
    const auto refuse = [&](std::string_view value, const std::string& why) {
        writer_.audit_refusal(command->device, {{command->parameter, std::string(value)}}, from_broker, why);
        answer(*command, payload, why);
    };
    if (payload.size() > max_payload_) {
        // Neither echoed nor parsed: the log and the answer say only how long it was.
        return refuse(fmt::format("({} bytes)", payload.size()),
                      fmt::format("the value is {} bytes long; at most {} are taken ([mqtt] max_payload)", payload.size(),
                                  max_payload_));
    }
    if (!writes_) return refuse(payload, "writes are off ([mqtt] writes = false)");
    // Before counting it in: a device found silent is refused at once, and never counts as busy.
    if (auto silent = writer_.refusal(command->device)) return refuse(payload, silent->message);
    if (auto refusal = admit()) return refuse(payload, *refusal);
    std::string text(payload);
    auto done = [this, command = *command, text](Result<WrittenValues> written) {
        answer(command, text, written ? std::string() : written.error().message);
        finished();
    };
    if (!writer_.write_async(command->device, {{command->parameter, std::move(text)}}, std::move(done), from_broker)) {
        answer(*command, payload,
               fmt::format("busy: the line of device \"{}\" has too many writes waiting; nothing was sent, write again later",
                           command->device));
        finished();
    }
}

void MqttCommands::refuse_retained(std::string_view topic, std::string_view payload) {
    const auto command = command_topic(prefix_, topic);
    if (!command) return;
    const std::string why = mqtt::retained_command_refusal(topic);
    writer_.audit_refusal(command->device, {{command->parameter, std::string(payload)}}, from_broker, why);
    answer(*command, payload, why);
}

std::optional<std::string> MqttCommands::admit() {
    std::lock_guard lock(mutex_);
    if (closed_) return "the gateway is stopping; nothing was sent";
    if (under_way_ >= max_commands_) {
        return fmt::format("busy: {} writes are already waiting for their lines; nothing was sent, write again once their "
                           "results are in", under_way_);
    }
    ++under_way_;
    return std::nullopt;
}

void MqttCommands::finished() {
    std::lock_guard lock(mutex_);
    if (--under_way_ == 0) all_answered_.notify_all();
}

// The result document, and a log line with the names and the value quoted and cut: a
// publisher's bytes never reach either raw.
void MqttCommands::answer(const CommandTopic& command, std::string_view payload, const std::string& error) {
    nlohmann::json result;
    const std::string what = fmt::format("{}.{} = {}", quoted_excerpt(command.device), quoted_excerpt(command.parameter),
                                         quoted_excerpt(payload));
    if (error.empty()) {
        result = {{"ok", true}, {"value", std::string(payload)}};
        if (log_) log_(fmt::format("{} written", what));
    } else {
        result = {{"ok", false}, {"error", error}};
        // The error may quote the value ("\"abc\" is not a number"): escaped and cut as well.
        if (log_) log_(fmt::format("{} refused: {}", what, printable_excerpt(error, 4 * peer_text_excerpt)));
    }
    if (publish_) {
        publish_(fmt::format("{}/{}/{}/set/result", prefix_, command.device, command.parameter), json_text(result));
    }
}

}  // namespace loopwire::gateway
