// The MQTT front's command path (gateway/mqtt_commands.hpp) on arbitrary topics and payloads,
// without a broker: the bytes a publisher could send to PREFIX/+/+/set, through the topic's
// parsing, the payload limit, the writer's checks against the TC10's profile and a line whose
// master fails every request at once. Properties: it never throws or aborts; every command
// topic gets exactly one answer, which is valid JSON with "ok"; a payload over max_payload is
// refused for its size; no log line holds a control byte or grows with the payload.
//
// Input: the first byte is the length of the topic's tail (after "fuzz/plant/"), then the
// tail, then the payload.
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "dead_line_master.hpp"
#include "fuzz_support.hpp"
#include "gateway/device_writer.hpp"
#include "gateway/engine.hpp"
#include "gateway/line_scheduler.hpp"
#include "gateway/mqtt_commands.hpp"

using namespace loopwire;

namespace {

struct Answers {
    std::mutex mutex;
    std::vector<std::pair<std::string, std::string>> published;
    std::vector<std::string> logged;
};

struct Front {
    Answers answers;
    std::shared_ptr<session::Master> master = std::make_shared<fuzz::DeadLineMaster>();
    std::shared_ptr<gateway::LineScheduler> line = std::make_shared<gateway::LineScheduler>(master);
    gateway::Engine engine;  // the writer's loop: goes after it
    gateway::DeviceWriter writer;
    gateway::MqttConfig config;
    gateway::MqttCommands commands;

    static gateway::MqttConfig configured() {
        gateway::MqttConfig config;
        config.prefix = "fuzz/plant";
        config.writes = true;
        config.max_payload = 64;
        return config;
    }
    static std::vector<gateway::WritableDevice> devices(const std::shared_ptr<gateway::LineScheduler>& line) {
        auto address = device::parse_device_address("tc10@3");
        fuzz::check(address.ok(), "the TC10 profile is built in");
        return {{"oven", *address, line}};
    }

    Front()
        : writer(engine, devices(line), std::chrono::milliseconds(1000)),
          config(configured()),
          commands(
              config, writer,
              [this](std::string topic, std::string payload) {
                  std::lock_guard lock(answers.mutex);
                  answers.published.emplace_back(std::move(topic), std::move(payload));
              },
              [this](const std::string& line_text) {
                  std::lock_guard lock(answers.mutex);
                  answers.logged.push_back(line_text);
              }) {}
};

Front& front() {
    static Front* instance = new Front();  // never destroyed: libFuzzer exits without unwinding
    return *instance;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    const std::size_t tail_length = std::min<std::size_t>(data[0], size - 1);
    const std::string tail(reinterpret_cast<const char*>(data + 1), tail_length);
    const std::string payload(reinterpret_cast<const char*>(data + 1 + tail_length), size - 1 - tail_length);
    const std::string topic = "fuzz/plant/" + tail;

    Front& f = front();
    {
        std::lock_guard lock(f.answers.mutex);
        f.answers.published.clear();
        f.answers.logged.clear();
    }
    const bool is_command = gateway::command_topic(f.config.prefix, topic).has_value();
    f.commands.take(topic, payload);
    // The dead line answers at once; its writer thread publishes shortly.
    while (f.commands.under_way() != 0) std::this_thread::yield();

    std::lock_guard lock(f.answers.mutex);
    fuzz::check(f.answers.published.size() == (is_command ? 1u : 0u), "a command gets one answer, anything else none");
    for (const auto& [result_topic, document] : f.answers.published) {
        fuzz::check(result_topic.ends_with("/set/result"), "answers go to set/result");
        const auto json = nlohmann::json::parse(document, nullptr, false);
        fuzz::check(!json.is_discarded() && json.is_object() && json.contains("ok") && json.at("ok").is_boolean(),
                    "the answer is a JSON object with a boolean ok");
        if (payload.size() > f.config.max_payload) {
            fuzz::check(json.at("ok") == false && document.find("max_payload") != std::string::npos,
                        "an oversized payload is refused for its size");
        }
    }
    for (const auto& line : f.answers.logged) {
        fuzz::check(line.size() < 3000, "a log line stays short whatever was sent");
        for (const char c : line) fuzz::check(static_cast<unsigned char>(c) >= 0x20, "no control byte reaches the log");
    }
    return 0;
}
