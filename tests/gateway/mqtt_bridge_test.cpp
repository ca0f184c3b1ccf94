// The gateway's MQTT front (gateway/mqtt_bridge.hpp) against a real mosquitto broker that each
// test starts on a free port: an in-process gateway on a simulated line publishes its status and
// values, takes writes and refuses bad ones, and comes back after the broker restarts. A libmosquitto
// client in the test watches the broker as any subscriber would. Skipped without /usr/sbin/mosquitto.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <poll.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <mosquitto.h>
#include <nlohmann/json.hpp>

#include "gateway/gateway.hpp"
#include "gateway/mqtt_documents.hpp"
#include "support/eventually.hpp"
#include "support/silenced_unit.hpp"
#include "support/log_lines.hpp"
#include "support/loopback_listener.hpp"
#include "support/mosquitto_broker.hpp"
#include "sparkplug/sparkplug_b.pb.h"
#include "support/profile_test_support.hpp"

extern char** environ;

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

const std::string prefix = "test/plant1";

const device::ProfileRegistry& profiles() { return device::testing::builtin_registry(); }

using testing::Broker;
using testing::Watcher;
using testing::eventually;
using testing::WatcherOptions;
using testing::deadline;
using testing::broker_program;
using testing::temporary_directory;

bool is_number(const std::string& text) {
    try {
        std::size_t used = 0;
        (void)std::stod(text, &used);
        return used > 0;
    } catch (const std::exception&) {
        return false;
    }
}

bool equals_number(const std::string& text, double value) { return is_number(text) && std::stod(text) == value; }

// A gateway with the simulated TC10 "oven" on a virtual line; `mqtt` is the [mqtt] table's
// further keys, `broker` its address.
std::unique_ptr<Gateway> open_gateway(const std::string& broker, bool writes, const std::string& mqtt,
                                      GatewayOptions options = {}, const std::string& source = "plant.toml",
                                      const std::string& parameters = R"("measured_value", "set_point")") {
    const std::string text = fmt::format(R"toml(
[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200&parity=none"
timeout = "500ms"
retries = 1

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "100ms"
parameters = [{}]

[modbus_tcp]
enabled = false

[mqtt]
broker = "{}"
prefix = "{}"
writes = {}
{}
)toml", parameters, broker, prefix, writes, mqtt);
    auto config = parse_gateway_config(text, source, profiles());
    if (!config) throw std::runtime_error(config.error().message);
    auto gateway = Gateway::open(*config, std::move(options));
    if (!gateway) throw std::runtime_error(gateway.error().message);
    return std::move(*gateway);
}

std::unique_ptr<Gateway> open_gateway(std::uint16_t port, bool writes) {
    return open_gateway(fmt::format("mqtt://127.0.0.1:{}", port), writes, "");
}

#define REQUIRE_BROKER()                                                                  \
    do {                                                                                  \
        if (!fs::exists(broker_program)) GTEST_SKIP() << broker_program << " is not installed (Debian package mosquitto)"; \
    } while (false)

TEST(MqttBridge, PublishesTheGatewayStatusEachDeviceAndItsValues) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port());
    auto gateway = open_gateway(broker.port(), false);

    EXPECT_TRUE(watcher.wait_for(prefix + "/status", "online")) << "no gateway status";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/status", "ok")) << "no device status";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/availability", "online")) << "no device availability";
    const auto value = watcher.wait_for(prefix + "/oven/measured_value", is_number);
    EXPECT_TRUE(value) << "no number for measured_value";
    const auto meta = watcher.wait_for(prefix + "/oven/measured_value/meta", [](const std::string&) { return true; });
    ASSERT_TRUE(meta) << "no meta for measured_value";
    const auto json = nlohmann::json::parse(*meta);
    // The unit as the profile gives it (the TC10's temperatures carry none: the device's own
    // setting says °C or °F).
    EXPECT_TRUE(json.at("unit").is_string()) << *meta;
    EXPECT_EQ(json.at("status"), "ok") << *meta;
    EXPECT_EQ(json.at("writable"), false) << *meta;
    const auto set_point_meta = watcher.wait_for(prefix + "/oven/set_point/meta", [](const std::string&) { return true; });
    ASSERT_TRUE(set_point_meta);
    const auto set_point = nlohmann::json::parse(*set_point_meta);
    EXPECT_EQ(set_point.at("writable"), true) << *set_point_meta;
    // The limits as the device holds them (the simulated TC10's SP.LL and SP.HL at dP 0), read
    // beside the polls though not polled themselves.
    EXPECT_EQ(set_point.at("min"), -1999.0) << *set_point_meta;
    EXPECT_EQ(set_point.at("max"), 9999.0) << *set_point_meta;

    // Writes are off in this gateway: refused, with the reason.
    watcher.publish(prefix + "/oven/set_point/set", "200");
    const auto refused = watcher.nth(prefix + "/oven/set_point/set/result", 1);
    ASSERT_TRUE(refused) << "no answer to a set";
    EXPECT_EQ(nlohmann::json::parse(*refused).at("ok"), false) << *refused;
    EXPECT_NE(refused->find("writes are off"), std::string::npos) << *refused;

    // A clean stop says "offline", for the gateway and for each device, whose status is then
    // "waiting" (nobody polls it), not the last word.
    gateway.reset();
    EXPECT_TRUE(watcher.wait_for(prefix + "/status", "offline")) << "no offline on a clean stop";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/availability", "offline")) << "no device offline on a clean stop";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/status", "waiting")) << "the device's last status stood after a clean stop";
}

// A stop that comes before the first poll has said anything of a device (a SIGTERM just after a
// reload) still says it "offline": the "online" a previous run left retained must not stand.
TEST(MqttBridge, AStopBeforeTheFirstPollSaysEveryDeviceOffline) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port());
    watcher.publish(prefix + "/oven/availability", "online", true);
    ASSERT_TRUE(watcher.wait_for(prefix + "/oven/availability", "online"));
    GatewayOptions options;
    // Nothing reaches unit 3, and its line waits 3 s for a reply: its first poll ends after the
    // stop (which waits for the exchange under way).
    options.virtual_bus_faults = [](const std::string&, ByteView bytes) {
        transport::BusFault fault;
        fault.drop = !bytes.empty() && bytes[0] == 3;
        return fault;
    };
    const std::string text = fmt::format(R"toml(
[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200&parity=none"
timeout = "3s"
retries = 0

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "1s"
parameters = ["measured_value"]

[modbus_tcp]
enabled = false

[mqtt]
broker = "mqtt://127.0.0.1:{}"
prefix = "{}"
)toml", broker.port(), prefix);
    auto config = parse_gateway_config(text, "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    auto gateway = Gateway::open(*config, std::move(options));
    ASSERT_TRUE(gateway) << gateway.error().message;
    ASSERT_TRUE(watcher.wait_for(prefix + "/status", "online"));
    gateway->reset();
    EXPECT_TRUE(watcher.wait_for(prefix + "/status", "offline"));
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/availability", "offline")) << "the oven's retained availability stayed \"online\"";
}

TEST(MqttBridge, WritesGoToTheDeviceAndBadOnesAreRefused) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port());
    // A command left retained on the broker before the gateway starts: replayed to it on
    // subscription, and refused with the reason, never written.
    watcher.publish(prefix + "/oven/set_point/set", "300", true);
    // Back to the watcher: the broker holds it before the gateway subscribes.
    ASSERT_TRUE(watcher.nth(prefix + "/oven/set_point/set", 1)) << "the retained command did not reach the broker";
    loopwire::testing::LogLines log;
    GatewayOptions options;
    options.log = log.sink();
    auto gateway = open_gateway(fmt::format("mqtt://127.0.0.1:{}", broker.port()), true, "", std::move(options));
    const std::string value = prefix + "/oven/set_point";
    const std::string result = prefix + "/oven/set_point/set/result";
    const auto retained = watcher.nth(result, 1);
    ASSERT_TRUE(retained) << "no answer to the retained command";
    EXPECT_EQ(nlohmann::json::parse(*retained).at("ok"), false) << *retained;
    EXPECT_NE(retained->find("retain flag"), std::string::npos) << *retained;
    EXPECT_TRUE(log.wait_for("\"300\" refused: published with the retain flag")) << "the refusal is not in the log";
    ASSERT_TRUE(watcher.wait_for(value, is_number)) << "no set_point value";

    watcher.publish(value + "/set", "200");
    const auto written = watcher.nth(result, 2);
    ASSERT_TRUE(written) << "no answer to a set";
    const auto answer = nlohmann::json::parse(*written);
    EXPECT_EQ(answer.at("ok"), true) << *written;
    EXPECT_EQ(answer.at("value"), "200") << *written;
    EXPECT_TRUE(watcher.wait_for(value, [](const std::string& text) { return equals_number(text, 200); }))
        << "the polls did not read the value written";

    watcher.publish(value + "/set", "99999");
    const auto out_of_range = watcher.nth(result, 3);
    ASSERT_TRUE(out_of_range) << "no answer to an out-of-range set";
    EXPECT_EQ(nlohmann::json::parse(*out_of_range).at("ok"), false) << *out_of_range;

    watcher.publish(prefix + "/oven/no_such_parameter/set", "1");
    const auto unknown = watcher.nth(prefix + "/oven/no_such_parameter/set/result", 1);
    ASSERT_TRUE(unknown);
    EXPECT_EQ(nlohmann::json::parse(*unknown).at("ok"), false) << *unknown;
    watcher.publish(prefix + "/kiln/set_point/set", "1");
    const auto no_device = watcher.nth(prefix + "/kiln/set_point/set/result", 1);
    ASSERT_TRUE(no_device);
    EXPECT_NE(no_device->find("no device"), std::string::npos) << *no_device;

    // A few polls later the value is still the one written: neither 99999 nor the retained 300.
    // (The latest value, not a status: on a loaded machine a poll 100 ms apart may be overdue
    // long enough for the value topic to say "stale" for a moment, as it must.)
    const auto answered = [&gateway] { return gateway->report().at(0).statistics.answered; };
    const auto answered_before = answered();
    ASSERT_TRUE(eventually([&] { return answered() >= answered_before + 5; })) << "the polls stopped";
    const auto last = watcher.wait_for(value, is_number);
    ASSERT_TRUE(last);
    EXPECT_TRUE(equals_number(*last, 200)) << *last;
    EXPECT_EQ(watcher.count(result), 3u) << "the retained command was answered more than once";
    watcher.publish(prefix + "/oven/set_point/set", "", true);  // clears the retained command
}

TEST(MqttBridge, ComesBackWhenTheBrokerRestarts) {
    REQUIRE_BROKER();
    Broker broker;
    testing::LogLines said;
    GatewayOptions options;
    options.log = said.sink();
    auto gateway = open_gateway(fmt::format("mqtt://127.0.0.1:{}", broker.port()), false, "", std::move(options));
    {
        Watcher watcher(broker.port());
        ASSERT_TRUE(watcher.wait_for(prefix + "/status", "online"));
        ASSERT_TRUE(watcher.wait_for(prefix + "/oven/measured_value", is_number));
    }
    broker.stop();
    ASSERT_TRUE(said.wait_for("connection lost")) << "the gateway never noticed its broker gone";
    broker.start();  // the same port; it kept nothing of before
    Watcher watcher(broker.port());
    EXPECT_TRUE(watcher.wait_for(prefix + "/status", "online")) << "the gateway did not reconnect";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/status", "ok")) << "the device status was not republished";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/measured_value", is_number)) << "the values were not republished";
}

TEST(MqttBridge, AGatewayStartsWithoutItsBroker) {
    REQUIRE_BROKER();
    testing::PortReservation reserved;  // the broker's, before it starts
    const std::uint16_t port = reserved.port();
    testing::LogLines said;
    GatewayOptions options;
    options.log = said.sink();
    // Nothing listens there yet: not an error.
    auto gateway = open_gateway(fmt::format("mqtt://127.0.0.1:{}", port), false, "", std::move(options));
    ASSERT_TRUE(said.wait_for("cannot reach the broker")) << "the gateway never tried its broker";
    Broker broker(std::move(reserved));
    Watcher watcher(port);
    EXPECT_TRUE(watcher.wait_for(prefix + "/status", "online")) << "the gateway did not connect once the broker came";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/measured_value", is_number));
}

// A broker's port whose queue of connections is full (a broker hung, or others' connections
// never taken): the gateway's connection to it can only wait for its handshake. It waits without
// holding the engine's loop, which the front shares with the polls (one executor): the
// polls go on meanwhile. A connect that blocked would hold them for the minutes TCP gives a
// handshake.
TEST(MqttBridge, AConnectionThatCannotCompleteHoldsUpNoPoll) {
    const testing::LoopbackListener full(0);
    // Takes the one place in its queue; the gateway's handshake is dropped from then on.
    const int queued = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(full.port());
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(::connect(queued, reinterpret_cast<sockaddr*>(&to), sizeof to), 0);
    auto gateway = open_gateway(fmt::format("mqtt://127.0.0.1:{}", full.port()), false, "");
    const auto answered = [&gateway] { return gateway->report().at(0).statistics.answered; };
    // Polls 100 ms apart: twenty more answered, within a bound that fails loudly, not a timing.
    const auto first = answered();
    EXPECT_TRUE(eventually([&] { return answered() >= first + 20; }))
        << "the polls stood still while the MQTT front waited for its broker";
    gateway.reset();  // while the handshake is still pending: the stop does not wait for it either
    ::close(queued);
}

// A port that takes TCP connections and answers each CONNECT with bytes that are not MQTT, then
// closes: another service where the broker was expected.
class NotABroker {
public:
    NotABroker() : thread_([this](std::stop_token stop) { serve(stop); }) {}
    std::uint16_t port() const { return listener_.port(); }
    // The connections taken so far.
    int connections() const { return connections_.load(); }

private:
    void serve(const std::stop_token& stop) {
        while (!stop.stop_requested()) {
            pollfd ready{listener_.fd(), POLLIN, 0};
            if (::poll(&ready, 1, 50) <= 0) continue;
            const int client = ::accept(listener_.fd(), nullptr, nullptr);
            if (client < 0) continue;
            ++connections_;
            char connect[256];
            pollfd readable{client, POLLIN, 0};
            if (::poll(&readable, 1, 1000) > 0) (void)::recv(client, connect, sizeof connect, 0);
            const char garbage[] = "HTTP/1.1 400 Bad Request\r\n\r\n";
            (void)::send(client, garbage, sizeof garbage - 1, MSG_NOSIGNAL);
            ::close(client);
        }
    }
    testing::LoopbackListener listener_;  // before the thread, which uses it
    std::atomic<int> connections_{0};
    std::jthread thread_;
};

// A port that answers TCP but not MQTT is said so once, not retried in silence.
TEST(MqttBridge, APortThatIsNotABrokerIsSaidToBeOne) {
    NotABroker not_a_broker;
    testing::LogLines said;
    GatewayOptions options;
    options.log = said.sink();
    auto gateway = open_gateway(fmt::format("mqtt://127.0.0.1:{}", not_a_broker.port()), false, "", std::move(options));
    EXPECT_TRUE(said.wait_for("ended before the broker accepted it")) << "nothing logged about the broker";
    EXPECT_TRUE(said.has("is this port an MQTT broker"));
    // More tries (0.5 s, then 1 s apart): a third connection comes once the second has failed
    // as the first did, which is still said once.
    ASSERT_TRUE(eventually([&] { return not_a_broker.connections() >= 3; })) << "the gateway stopped trying";
    EXPECT_EQ(said.count("ended before the broker accepted it"), 1);
}

// Runs a program to its end; its output goes to `log`. True when it exits 0.
bool run(const std::vector<std::string>& words, const fs::path& log) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    std::vector<std::string> copy = words;
    std::vector<char*> argv;
    for (auto& word : copy) argv.push_back(word.data());
    argv.push_back(nullptr);
    pid_t pid = -1;
    const int rc = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    int status = 0;
    return rc == 0 && ::waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

using testing::LogLines;

// A gateway taking writes and announcing its parameters to Home Assistant.
std::unique_ptr<Gateway> open_discovering_gateway(const Broker& broker, const std::string& parameters) {
    return open_gateway(fmt::format("mqtt://127.0.0.1:{}", broker.port()), true, "discovery = \"homeassistant\"", {},
                        "plant.toml", parameters);
}

WatcherOptions every_topic() {
    WatcherOptions everything;
    everything.topics = "#";
    return everything;
}

TEST(MqttBridge, MetaAndHomeAssistantDiscoveryDescribeEveryPolledParameter) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_topic());
    auto gateway = open_discovering_gateway(broker, R"("measured_value", "set_point", "control_state", "alarm_1_state")");
    const auto any = [](const std::string&) { return true; };

    const auto meta_text = watcher.wait_for(prefix + "/oven/set_point/meta", any);
    ASSERT_TRUE(meta_text);
    const auto meta = nlohmann::json::parse(*meta_text);
    for (const char* key : {"unit", "decimals", "writable", "min", "max", "enum", "mnemonic", "status", "error", "last_error"}) {
        EXPECT_TRUE(meta.contains(key)) << key << " missing in " << *meta_text;
    }
    EXPECT_TRUE(meta.at("decimals").is_number_integer()) << *meta_text;
    EXPECT_FALSE(meta.at("mnemonic").get<std::string>().empty()) << *meta_text;
    const auto state_meta = watcher.wait_for(prefix + "/oven/control_state/meta", any);
    ASSERT_TRUE(state_meta);
    EXPECT_EQ(nlohmann::json::parse(*state_meta).at("enum"),
              (nlohmann::json{{"0", "auto"}, {"1", "manual"}, {"2", "standby"}}))
        << *state_meta;

    // One document per parameter, in the component that fits it; the gateway's name is the
    // prefix's last level.
    const std::string head = "homeassistant/";
    const auto number_text = watcher.wait_for(head + "number/plant1_oven_set_point/config", any);
    ASSERT_TRUE(number_text) << "no number for the writable set_point";
    const auto number = nlohmann::json::parse(*number_text);
    EXPECT_EQ(number.at("unique_id"), "plant1_oven_set_point");
    EXPECT_EQ(number.at("state_topic"), prefix + "/oven/set_point");
    EXPECT_EQ(number.at("command_topic"), prefix + "/oven/set_point/set");
    EXPECT_TRUE(number.at("step").is_number()) << *number_text;
    // SP.LL and SP.HL are not polled: the widest the device allows them (the manual's display
    // range, -1999 .. 9999 counts), never what the word can hold (-32768 .. 32767).
    EXPECT_EQ(number.value("min", 0.0), -1999.0) << *number_text;
    EXPECT_EQ(number.value("max", 0.0), 9999.0) << *number_text;
    EXPECT_EQ(number.at("value_template"), "{{ value if value | is_number else None }}");
    EXPECT_EQ(number.at("device").at("via_device"), "plant1");
    const auto gateway_text = watcher.wait_for(head + "binary_sensor/plant1_status/config", any);
    ASSERT_TRUE(gateway_text) << "no device for the gateway itself";
    const auto gateway_document = nlohmann::json::parse(*gateway_text);
    EXPECT_EQ(gateway_document.at("state_topic"), prefix + "/status");
    EXPECT_EQ(gateway_document.at("device").at("identifiers"), nlohmann::json::array({"plant1"}));
    EXPECT_TRUE(gateway_document.at("device").contains("sw_version"));
    EXPECT_EQ(number.at("device").at("manufacturer"), "Yokogawa");
    EXPECT_EQ(number.at("device").at("model"), "TC10");
    EXPECT_EQ(number.at("device").at("identifiers"), nlohmann::json::array({"plant1_oven"}));
    EXPECT_EQ(number.at("availability_mode"), "all");
    ASSERT_EQ(number.at("availability").size(), 2u);
    EXPECT_EQ(number.at("availability")[0].at("topic"), prefix + "/status");
    EXPECT_EQ(number.at("availability")[1].at("topic"), prefix + "/oven/availability");
    EXPECT_EQ(number.at("availability")[1].at("payload_available"), "online");

    const auto sensor_text = watcher.wait_for(head + "sensor/plant1_oven_measured_value/config", any);
    ASSERT_TRUE(sensor_text) << "no sensor for the read-only measured_value";
    EXPECT_FALSE(nlohmann::json::parse(*sensor_text).contains("command_topic")) << *sensor_text;
    const auto binary_text = watcher.wait_for(head + "binary_sensor/plant1_oven_alarm_1_state/config", any);
    ASSERT_TRUE(binary_text) << "no binary_sensor for the on/off alarm_1_state";
    EXPECT_EQ(nlohmann::json::parse(*binary_text).at("payload_on"), "on");
    const auto select_text = watcher.wait_for(head + "select/plant1_oven_control_state/config", any);
    ASSERT_TRUE(select_text) << "no select for the writable enum control_state";
    const auto select = nlohmann::json::parse(*select_text);
    EXPECT_EQ(select.at("options"), nlohmann::json::array({"auto", "manual", "standby"}));

    // What Home Assistant would send on the select's command topic goes to the device.
    watcher.publish(select.at("command_topic").get<std::string>(), "standby");
    const auto result = watcher.nth(prefix + "/oven/control_state/set/result", 1);
    ASSERT_TRUE(result);
    EXPECT_EQ(nlohmann::json::parse(*result).at("ok"), true) << *result;
    EXPECT_TRUE(watcher.wait_for(select.at("state_topic").get<std::string>(), "standby"));
    for (const auto& topic : watcher.topics("")) {
        EXPECT_EQ(topic.find_first_of(" +#"), std::string::npos) << topic;
    }
}

// The TC10's temperatures take their unit from its temperature_unit word: Home Assistant gets
// the unit the device is set to, a temperature device class, and a thermostat (climate) for the
// loop; set to °F on the device, every document says °F.
TEST(MqttBridge, HomeAssistantSeesTheTc10AsAThermostatInTheUnitItIsSetTo) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_topic());
    auto gateway = open_discovering_gateway(broker, R"("measured_value", "set_point", "temperature_unit")");
    const auto in_unit = [](const char* key, const char* unit) {
        return [key, unit](const std::string& text) {
            const auto document = nlohmann::json::parse(text, nullptr, false);
            return document.is_object() && document.value(key, std::string()) == unit;
        };
    };
    const std::string sensor_topic = "homeassistant/sensor/plant1_oven_measured_value/config";
    const std::string climate_topic = "homeassistant/climate/plant1_oven_control_loop/config";

    const auto sensor = watcher.wait_for(sensor_topic, in_unit("unit_of_measurement", "°C"));
    ASSERT_TRUE(sensor) << "the measured value's unit is not the device's °C";
    EXPECT_EQ(nlohmann::json::parse(*sensor).at("device_class"), "temperature") << *sensor;
    const auto climate_text = watcher.wait_for(climate_topic, in_unit("temperature_unit", "C"));
    ASSERT_TRUE(climate_text) << "no thermostat for the TC10's control loop";
    const auto climate = nlohmann::json::parse(*climate_text);
    EXPECT_EQ(climate.at("current_temperature_topic"), prefix + "/oven/measured_value");
    EXPECT_EQ(climate.at("temperature_state_topic"), prefix + "/oven/set_point");
    EXPECT_EQ(climate.at("temperature_command_topic"), prefix + "/oven/set_point/set");
    // The set point's limit words are not polled: the widest the device allows, not ±32768.
    EXPECT_EQ(climate.value("min_temp", 0.0), -1999.0) << *climate_text;
    EXPECT_EQ(climate.value("max_temp", 0.0), 9999.0) << *climate_text;
    EXPECT_EQ(climate.at("availability").size(), 2u);
    EXPECT_EQ(climate.at("device").at("identifiers"), nlohmann::json::array({"plant1_oven"}));

    // What Home Assistant would send for a new target goes to the set point.
    watcher.publish(climate.at("temperature_command_topic").get<std::string>(), "123");
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/set_point", [](const std::string& text) { return text.rfind("123", 0) == 0; }));

    watcher.publish(prefix + "/oven/temperature_unit/set", "F");
    EXPECT_TRUE(watcher.wait_for(sensor_topic, in_unit("unit_of_measurement", "°F"))) << "the sensor still says °C";
    EXPECT_TRUE(watcher.wait_for(climate_topic, in_unit("temperature_unit", "F"))) << "the thermostat still says C";
}

// The set point's limits are the device's own SP.LL and SP.HL: lowered on the device, the
// number, the thermostat and /meta say so.
TEST(MqttBridge, HomeAssistantAndMetaShowTheLimitsTheDeviceHolds) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_topic());
    auto gateway = open_discovering_gateway(broker, R"("measured_value", "set_point", "set_point_high_limit")");
    const auto with_number = [](const char* key, double wanted) {
        return [key, wanted](const std::string& text) {
            const auto document = nlohmann::json::parse(text, nullptr, false);
            return document.is_object() && document.contains(key) && document.at(key).is_number() &&
                   document.at(key).get<double>() == wanted;
        };
    };
    const std::string number_topic = "homeassistant/number/plant1_oven_set_point/config";
    const std::string climate_topic = "homeassistant/climate/plant1_oven_control_loop/config";
    EXPECT_TRUE(watcher.wait_for(number_topic, with_number("max", 9999.0))) << "the number's max is not the device's SP.HL";
    EXPECT_TRUE(watcher.wait_for(climate_topic, with_number("max_temp", 9999.0)));

    watcher.publish(prefix + "/oven/set_point_high_limit/set", "500");
    EXPECT_TRUE(watcher.wait_for(number_topic, with_number("max", 500.0))) << "SP.HL lowered, the number still offers more";
    EXPECT_TRUE(watcher.wait_for(climate_topic, with_number("max_temp", 500.0)));
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/set_point/meta", with_number("max", 500.0)));
    EXPECT_TRUE(watcher.wait_for(number_topic, with_number("min", -1999.0)));
}

TEST(MqttDocuments, AClimateIsForATemperatureLoopOnly) {
    MqttConfig mqtt;
    mqtt.prefix = "loopwire/plant1";
    mqtt.gateway_name = "plant1";
    const auto tc10 = profiles().find("tc10");
    const auto ac20 = profiles().find("ac20");
    ASSERT_TRUE(tc10 && ac20);
    EXPECT_TRUE(climate_document(mqtt, "oven", **tc10, {"°C", 1}));
    EXPECT_FALSE(climate_document(mqtt, "oven", **tc10, {"EU", 1})) << "a loop in engineering units is no thermostat";
    EXPECT_FALSE(climate_document(mqtt, "furnace", **ac20, {"%C", 2})) << "carbon potential is no temperature";
    const auto read_only = climate_document(mqtt, "oven", **tc10, {"°F", 0});
    ASSERT_TRUE(read_only);
    EXPECT_FALSE(read_only->config.contains("temperature_command_topic")) << "writes are off, yet HA may set the target";
    EXPECT_EQ(read_only->config.at("temperature_unit"), "F");
    EXPECT_EQ(read_only->config.at("temp_step"), 1.0);
    EXPECT_EQ(read_only->config.at("precision"), 1.0);
    EXPECT_EQ(read_only->topic, climate_topic(mqtt, "oven"));
    EXPECT_FALSE(read_only->config.contains("preset_modes")) << "presets before the mode word was polled";

    // With the TC10's control_state (alias MODE) polled: its modes are the presets, standby is
    // Home Assistant's off and every other mode heats.
    mqtt.writes = true;
    const auto with_modes = climate_document(mqtt, "oven", **tc10, {"°C", 1, true});
    ASSERT_TRUE(with_modes);
    const auto& doc = with_modes->config;
    EXPECT_EQ(doc.at("preset_modes"), nlohmann::json::array({"auto", "manual", "standby"}));
    EXPECT_EQ(doc.at("preset_mode_state_topic"), "loopwire/plant1/oven/control_state");
    EXPECT_EQ(doc.at("preset_mode_command_topic"), "loopwire/plant1/oven/control_state/set");
    EXPECT_EQ(doc.at("modes"), nlohmann::json::array({"heat", "off"}));
    EXPECT_EQ(doc.at("mode_state_template"),
              "{{ ('off' if value == \"standby\" else 'heat') if value in [\"auto\",\"manual\",\"standby\"] else None }}");
    EXPECT_EQ(doc.at("mode_command_template"), "{{ \"standby\" if value == 'off' else \"auto\" }}");
    EXPECT_EQ(doc.at("mode_command_topic"), "loopwire/plant1/oven/control_state/set");
    const auto no_mode_word = climate_document(mqtt, "furnace", **ac20, {"°C", 1, true});
    ASSERT_TRUE(no_mode_word);
    EXPECT_FALSE(no_mode_word->config.contains("preset_modes")) << "the AC20's profile names no MODE";
    EXPECT_EQ(no_mode_word->config.at("modes"), nlohmann::json::array({"heat"}));
    EXPECT_EQ(no_mode_word->config.at("mode_state_topic"), "loopwire/plant1/furnace/main_set_point");
    EXPECT_EQ(friendly_name(*(*tc10)->find("measured_value")), "Measured value (rV)");
    EXPECT_EQ(friendly_name(*(*tc10)->find("output_power")), "Output power");
    EXPECT_EQ(friendly_name(*(*ac20)->find("main_set_point")), "Main set point");
    EXPECT_EQ(device_class_of("°C"), "temperature");
    EXPECT_EQ(device_class_of("%"), "");
}

// Configuration words are Home Assistant's `config` entities when commanded and `diagnostic`
// when only shown; the loop's set point, though kept across power-off, is neither. An alarm
// word is one binary_sensor per named bit, reading its bit from the word's text.
TEST(MqttDocuments, ConfigurationIsCategorisedAndEveryAlarmBitIsABinarySensor) {
    MqttConfig mqtt;
    mqtt.prefix = "loopwire/plant1";
    mqtt.gateway_name = "plant1";
    const auto found = profiles().find("tc10");
    ASSERT_TRUE(found);
    const device::Profile& tc10 = **found;
    mqtt.writes = true;
    EXPECT_EQ(discovery_document(mqtt, "oven", tc10, *tc10.find("temperature_unit")).config.at("entity_category"), "config");
    EXPECT_FALSE(discovery_document(mqtt, "oven", tc10, *tc10.find("set_point")).config.contains("entity_category"));
    EXPECT_FALSE(discovery_document(mqtt, "oven", tc10, *tc10.find("measured_value")).config.contains("entity_category"));
    mqtt.writes = false;
    EXPECT_EQ(discovery_document(mqtt, "oven", tc10, *tc10.find("temperature_unit")).config.at("entity_category"), "diagnostic");

    EXPECT_TRUE(bit_documents(mqtt, "oven", tc10, *tc10.find("measured_value")).empty());
    const auto bits = bit_documents(mqtt, "oven", tc10, *tc10.find("alarm_status"));
    ASSERT_EQ(bits.size(), 7U) << "one per named bit of the TC10's alarm word";
    const auto loop_break = std::find_if(bits.begin(), bits.end(), [](const DiscoveryDocument& document) {
        return document.topic == "homeassistant/binary_sensor/plant1_oven_alarm_status_loop_break_alarm/config";
    });
    ASSERT_NE(loop_break, bits.end());
    EXPECT_EQ(loop_break->config.at("state_topic"), "loopwire/plant1/oven/alarm_status");
    EXPECT_EQ(loop_break->config.at("device_class"), "problem");
    EXPECT_EQ(loop_break->config.at("value_template"),
              "{{ ('ON' if \"loop_break_alarm\" in value[1:-1].split(', ') else 'OFF') if value[:1] == '{' else None }}");
    EXPECT_EQ(loop_break->config.at("unique_id"), "plant1_oven_alarm_status_loop_break_alarm");
}

TEST(MqttDocuments, DiscoveryIdsAndTopicsNeverHoldWildcardsSlashesOrSpaces) {
    const auto config = parse_gateway_config(R"toml(
[[lines]]
name = "sim"
link = "rtu:virtual?baud=19200"
[[lines.devices]]
name = "oven"
device = "tc10@3"
[mqtt]
broker = "mqtt://127.0.0.1"
prefix = "site a/gw #1+x"
discovery = "homeassistant"
discovery_prefix = "ha/x"
)toml", "plant.toml", profiles());
    ASSERT_FALSE(config) << "a prefix with '#' or '+' was taken";
    auto mqtt = MqttConfig{};
    mqtt.prefix = "site a/gw 1";
    mqtt.gateway_name = "gw 1/+#";  // as if given unchecked
    mqtt.discovery_prefix = "ha";
    const auto found = profiles().find("tc10");
    ASSERT_TRUE(found);
    const device::Profile& tc10 = **found;
    const auto document = discovery_document(mqtt, "oven", tc10, *tc10.find("set_point"));
    EXPECT_EQ(document.topic, "ha/sensor/gw_1____oven_set_point/config");
    EXPECT_EQ(document.config.at("unique_id"), "gw_1____oven_set_point");
    EXPECT_EQ(sanitized_level("a b/c+d#e"), "a_b_c_d_e");
    EXPECT_EQ(sanitized_level(""), "_");
}

TEST(MqttBridge, RepublishesUnchangedValuesEveryInterval) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port());
    auto gateway = open_gateway(fmt::format("mqtt://127.0.0.1:{}", broker.port()), false, "republish = \"300ms\"", {},
                                "plant.toml", R"("set_point")");
    const std::string topic = prefix + "/oven/set_point";
    const auto first = watcher.nth(topic, 1);
    ASSERT_TRUE(first);
    // The set point does not move by itself: later copies are the republishing.
    const auto fourth = watcher.nth(topic, 4);
    ASSERT_TRUE(fourth) << "an unchanged value was not published again every 300 ms";
    EXPECT_EQ(*fourth, *first);
}

TEST(MqttBridge, AWriteToADeviceThatDoesNotAnswerIsRefusedAtOnce) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port());
    auto silent = std::make_shared<std::atomic<bool>>(false);
    GatewayOptions options;
    // Every frame to or from unit 3 dropped once `silent` is set (an RTU frame starts with its unit).
    options.virtual_bus_faults = [silent](const std::string&, ByteView bytes) {
        transport::BusFault fault;
        fault.drop = silent->load() && !bytes.empty() && bytes[0] == 3;
        return fault;
    };
    auto gateway = open_gateway(fmt::format("mqtt://127.0.0.1:{}", broker.port()), true, "", std::move(options));
    ASSERT_TRUE(watcher.wait_for(prefix + "/oven/status", "ok"));
    *silent = true;
    ASSERT_TRUE(watcher.wait_for(prefix + "/oven/status", "no-reply")) << "the polls never found the oven silent";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/availability", "offline")) << "a silent device stayed available";
    watcher.publish(prefix + "/oven/set_point/set", "210");
    const auto result = watcher.nth(prefix + "/oven/set_point/set/result", 1);
    ASSERT_TRUE(result) << "no answer to a write while the device is silent";
    const auto answer = nlohmann::json::parse(*result);
    EXPECT_EQ(answer.at("ok"), false) << *result;
    EXPECT_NE(answer.at("error").get<std::string>().find("does not answer"), std::string::npos) << *result;
}

TEST(MqttBridge, WhatChangedWhileTheBrokerWasAwayIsPublishedOnReturn) {
    REQUIRE_BROKER();
    Broker broker;
    auto silent = std::make_shared<std::atomic<bool>>(false);
    GatewayOptions options;
    options.virtual_bus_faults = [silent](const std::string&, ByteView bytes) {
        transport::BusFault fault;
        fault.drop = silent->load() && !bytes.empty() && bytes[0] == 3;
        return fault;
    };
    auto gateway = open_gateway(fmt::format("mqtt://127.0.0.1:{}", broker.port()), false, "", std::move(options));
    const std::string topic = prefix + "/oven/measured_value";
    std::mutex mutex;
    std::string latest;  // what the polls found last: a value, or why there is none
    auto subscription = gateway->subscribe([&](const ValueChange& change) {
        if (change.parameter != "measured_value") return;
        std::lock_guard lock(mutex);
        latest = change.value ? change.text : change.status;
    });
    std::string before;
    {
        Watcher watcher(broker.port());
        const auto seen = watcher.wait_for(topic, is_number);
        ASSERT_TRUE(seen);
        before = *seen;
    }
    broker.stop();
    // While the broker is away the oven stops answering: its value becomes "no-reply".
    *silent = true;
    ASSERT_TRUE(eventually([&] {
        std::lock_guard lock(mutex);
        return latest == "no-reply";
    })) << "the polls never found the oven silent";
    broker.start();
    Watcher watcher(broker.port());
    ASSERT_TRUE(watcher.wait_for(prefix + "/status", "online"));
    // The last state wins, and the number from before the broker went away does not come back.
    EXPECT_TRUE(watcher.wait_for(topic, "no-reply")) << "the broker never got the value's last state";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/status", "no-reply")) << "the broker never got the device's last status";
    const auto first = watcher.nth(topic, 1);
    ASSERT_TRUE(first);
    EXPECT_NE(*first, before) << "the value from before the broker went away came back";
}

// --- TLS and credentials ----------------------------------------------------------------------

// A throwaway certificate authority and a server certificate for 127.0.0.1, made with openssl.
struct TestCertificates {
    fs::path directory = temporary_directory();
    fs::path ca = directory / "ca.crt";
    fs::path server_cert = directory / "server.crt";
    fs::path server_key = directory / "server.key";
    bool made = false;

    TestCertificates() {
        const fs::path log = directory / "openssl.log";
        const auto d = directory.string();
        made = run({"openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj", "/CN=loopwire test CA",
                    "-keyout", d + "/ca.key", "-out", ca.string()}, log) &&
               run({"openssl", "req", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=127.0.0.1", "-addext",
                    "subjectAltName=IP:127.0.0.1", "-keyout", server_key.string(), "-out", d + "/server.csr"}, log) &&
               run({"openssl", "x509", "-req", "-in", d + "/server.csr", "-CA", ca.string(), "-CAkey", d + "/ca.key",
                    "-CAcreateserial", "-days", "2", "-copy_extensions", "copy", "-out", server_cert.string()}, log);
        fs::permissions(server_key, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read |
                                        fs::perms::others_read);  // the broker may run as another user
    }
    ~TestCertificates() {
        std::error_code ignored;
        fs::remove_all(directory, ignored);
    }
};

TEST(MqttBridge, TlsWithAPasswordAndAWrongPasswordRetried) {
    REQUIRE_BROKER();
    TestCertificates certificates;
    ASSERT_TRUE(certificates.made) << "openssl could not make the test certificates (Debian package openssl)";
    const fs::path passwords = certificates.directory / "passwd";
    const fs::path log = certificates.directory / "passwd.log";
    ASSERT_TRUE(run({"mosquitto_passwd", "-c", "-b", passwords.string(), "gateway", "right-one"}, log));
    ASSERT_TRUE(run({"mosquitto_passwd", "-b", passwords.string(), "watcher", "watching"}, log));
    fs::permissions(passwords, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::others_read);
    Broker broker(fmt::format("cafile {}\ncertfile {}\nkeyfile {}\nallow_anonymous false\npassword_file {}\n",
                              certificates.ca.string(), certificates.server_cert.string(),
                              certificates.server_key.string(), passwords.string()));
    WatcherOptions options;
    options.ca_file = certificates.ca.string();
    options.username = "watcher";
    options.password = "watching";
    Watcher watcher(broker.port(), options);

    // The gateway's password, in a file only its owner reads; a wrong one first.
    const fs::path password_file = certificates.directory / "gateway.password";
    std::ofstream(password_file) << "wrong-one\n";
    fs::permissions(password_file, fs::perms::owner_read | fs::perms::owner_write);
    const fs::path config_file = certificates.directory / "plant.toml";  // relative files are beside it
    LogLines lines;
    GatewayOptions gateway_options;
    gateway_options.log = lines.sink();
    auto gateway = open_gateway(fmt::format("mqtts://127.0.0.1:{}", broker.port()), false,
                                "ca_file = \"ca.crt\"\nusername = \"gateway\"\npassword_file = \"gateway.password\"",
                                std::move(gateway_options), config_file.string());
    EXPECT_TRUE(lines.wait_for("refused the connection")) << "no log line for the refused password";
    EXPECT_TRUE(lines.has("not authorised")) << "the log does not say why";
    EXPECT_EQ(watcher.count(prefix + "/status"), 0u);

    // The broker is told the password the gateway has: the gateway, still trying, gets in.
    ASSERT_TRUE(run({"mosquitto_passwd", "-b", passwords.string(), "gateway", "wrong-one"}, log));
    broker.reload();
    EXPECT_TRUE(watcher.wait_for(prefix + "/status", "online")) << "the gateway did not connect over TLS\n" << broker.log();
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/measured_value", is_number));
}

// --- redelivered commands -----------------------------------------------------------------------

// Just enough of an MQTT 3.1.1 broker, on a socket, to send the gateway what a real broker
// sends after a reconnect in a persistent session: a QoS 1 PUBLISH again, with the DUP flag and
// the same packet identifier. It acknowledges what the gateway publishes and keeps it.
class ScriptedBroker {
public:
    ScriptedBroker() {
        listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
        sockaddr_in address{};
        address.sin_family = AF_INET;
        address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        socklen_t length = sizeof address;
        if (::bind(listener_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 || ::listen(listener_, 4) != 0 ||
            ::getsockname(listener_, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
            throw std::runtime_error("cannot listen");
        }
        port_ = ntohs(address.sin_port);
    }
    ~ScriptedBroker() {
        drop();
        ::close(listener_);
    }
    ScriptedBroker(const ScriptedBroker&) = delete;
    ScriptedBroker& operator=(const ScriptedBroker&) = delete;
    std::uint16_t port() const { return port_; }

    // Takes the gateway's next connection: CONNECT, CONNACK (with the session-present flag),
    // SUBSCRIBE, SUBACK. False at the deadline.
    bool accept(bool session_present) {
        pollfd waiting{listener_, POLLIN, 0};
        if (::poll(&waiting, 1, static_cast<int>(std::chrono::milliseconds(deadline).count())) != 1) return false;
        client_ = ::accept(listener_, nullptr, nullptr);
        buffer_.clear();
        auto connect = next_packet();
        if (!connect || (connect->first >> 4) != 1) return false;
        send({0x20, 0x02, static_cast<std::uint8_t>(session_present ? 1 : 0), 0x00});
        while (auto packet = next_packet()) {
            if ((packet->first >> 4) == 8) {  // SUBSCRIBE: granted QoS 1
                send({0x90, 0x03, packet->second[0], packet->second[1], 0x01});
                return true;
            }
        }
        return false;
    }

    void publish(std::uint16_t mid, const std::string& topic, const std::string& payload, bool dup) {
        std::vector<std::uint8_t> body{static_cast<std::uint8_t>(topic.size() >> 8), static_cast<std::uint8_t>(topic.size() & 0xFF)};
        body.insert(body.end(), topic.begin(), topic.end());
        body.push_back(static_cast<std::uint8_t>(mid >> 8));
        body.push_back(static_cast<std::uint8_t>(mid & 0xFF));
        body.insert(body.end(), payload.begin(), payload.end());
        std::vector<std::uint8_t> packet{static_cast<std::uint8_t>(0x32 | (dup ? 0x08 : 0x00))};  // PUBLISH, QoS 1
        for (std::size_t left = body.size();;) {  // remaining length (MQTT 3.1.1, 2.2.3)
            std::uint8_t digit = static_cast<std::uint8_t>(left % 128);
            left /= 128;
            packet.push_back(left > 0 ? static_cast<std::uint8_t>(digit | 0x80) : digit);
            if (left == 0) break;
        }
        packet.insert(packet.end(), body.begin(), body.end());
        send(packet);
    }

    // Reads what the gateway sends until it publishes on one of `topics`: that topic and its
    // payload, or nullopt.
    std::optional<std::pair<std::string, std::string>> published(const std::vector<std::string>& topics) {
        while (auto packet = next_packet()) {
            const std::uint8_t type = packet->first >> 4;
            if (type == 12) send({0xD0, 0x00});  // PINGREQ
            if (type != 3) continue;
            const auto& body = packet->second;
            const std::size_t length = static_cast<std::size_t>(body[0] << 8 | body[1]);
            const std::string name(body.begin() + 2, body.begin() + 2 + static_cast<std::ptrdiff_t>(length));
            std::size_t at = 2 + length;
            if (((packet->first >> 1) & 3) > 0) {  // QoS 1: PUBACK with its identifier
                send({0x40, 0x02, body[at], body[at + 1]});
                at += 2;
            }
            if (std::find(topics.begin(), topics.end(), name) != topics.end()) {
                return std::pair{name, std::string(body.begin() + static_cast<std::ptrdiff_t>(at), body.end())};
            }
        }
        return std::nullopt;
    }

    // The connection breaks (as if the gateway's PUBACK never reached the broker).
    void drop() {
        if (client_ >= 0) ::close(client_);
        client_ = -1;
    }

private:
    void send(const std::vector<std::uint8_t>& bytes) { (void)::send(client_, bytes.data(), bytes.size(), MSG_NOSIGNAL); }

    // The next whole packet: its first byte and its body; nullopt at the deadline or on EOF.
    std::optional<std::pair<std::uint8_t, std::vector<std::uint8_t>>> next_packet() {
        const auto give_up = std::chrono::steady_clock::now() + deadline;
        for (;;) {
            if (buffer_.size() >= 2) {
                std::size_t length = 0;
                std::size_t used = 1;
                unsigned shift = 0;
                bool whole = false;
                while (used < buffer_.size() && used <= 4) {
                    length |= static_cast<std::size_t>(buffer_[used] & 0x7F) << shift;
                    shift += 7;
                    if ((buffer_[used++] & 0x80) == 0) {
                        whole = true;
                        break;
                    }
                }
                if (whole && buffer_.size() >= used + length) {
                    std::pair<std::uint8_t, std::vector<std::uint8_t>> packet{
                        buffer_[0], {buffer_.begin() + static_cast<std::ptrdiff_t>(used),
                                     buffer_.begin() + static_cast<std::ptrdiff_t>(used + length)}};
                    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(used + length));
                    return packet;
                }
            }
            const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(give_up - std::chrono::steady_clock::now());
            if (left.count() <= 0) return std::nullopt;
            pollfd readable{client_, POLLIN, 0};
            if (::poll(&readable, 1, static_cast<int>(left.count())) != 1) return std::nullopt;
            std::uint8_t chunk[4096];
            const auto got = ::recv(client_, chunk, sizeof chunk, 0);
            if (got <= 0) return std::nullopt;
            buffer_.insert(buffer_.end(), chunk, chunk + got);
        }
    }

    int listener_ = -1;
    int client_ = -1;
    std::uint16_t port_ = 0;
    std::vector<std::uint8_t> buffer_;
};

TEST(MqttBridge, PayloadsThatAreNotUtf8OrTooLongAreRefusedAndTheNextWriteGoes) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port());
    LogLines lines;
    GatewayOptions options;
    options.log = lines.sink();
    auto gateway = open_gateway(fmt::format("mqtt://127.0.0.1:{}", broker.port()), true, "", std::move(options));
    const std::string value = prefix + "/oven/set_point";
    const std::string result = value + "/set/result";
    ASSERT_TRUE(watcher.wait_for(value, is_number)) << "no set_point value";

    // One byte that is not UTF-8: once the end of the process (nlohmann's type_error 316 when
    // the refusal echoed it).
    watcher.publish(value + "/set", "\xff");
    const auto not_utf8 = watcher.nth(result, 1);
    ASSERT_TRUE(not_utf8) << "no answer to a payload that is not UTF-8";
    const auto refusal = nlohmann::json::parse(*not_utf8, nullptr, false);
    ASSERT_FALSE(refusal.is_discarded()) << *not_utf8;
    EXPECT_EQ(refusal.at("ok"), false) << *not_utf8;

    // 200 KB: refused for its size, neither echoed nor logged whole.
    watcher.publish(value + "/set", std::string(200 * 1024, '7'));
    const auto oversized = watcher.nth(result, 2);
    ASSERT_TRUE(oversized) << "no answer to a 200 KB payload";
    EXPECT_EQ(nlohmann::json::parse(*oversized).at("ok"), false) << *oversized;
    EXPECT_NE(oversized->find("204800 bytes long; at most 1024 are taken ([mqtt] max_payload)"), std::string::npos) << *oversized;
    EXPECT_LT(oversized->size(), 400u);

    // The next valid write goes through.
    watcher.publish(value + "/set", "205");
    const auto written = watcher.nth(result, 3);
    ASSERT_TRUE(written) << "no answer to the valid write after the hostile ones";
    EXPECT_EQ(nlohmann::json::parse(*written).at("ok"), true) << *written;

    // The log quotes payloads escaped and cut.
    EXPECT_TRUE(lines.has("\"set_point\" = \"\\xff\" refused"));
    EXPECT_TRUE(lines.has("\"" + std::string(64, '7') + "\"\u2026 (204800 bytes) refused"));
    for (const auto& line : lines.all()) {
        EXPECT_LT(line.size(), 1000u) << line.substr(0, 200);
        EXPECT_EQ(line.find('\xff'), std::string::npos) << "a raw byte reached the log: " << line.substr(0, 200);
    }
}

TEST(MqttBridge, AWriteToOneLineIsAnsweredWhileAnotherLineHoldsItsWrites) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port());
    support::SilencedUnit kiln(4);
    const std::string text = fmt::format(R"toml(
[[lines]]
name = "fast"
link = "rtu:virtual?baud=115200&parity=none"
timeout = "500ms"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "100ms"
parameters = ["set_point"]

[[lines]]
name = "slow"
link = "rtu:virtual?baud=115200&parity=none"
timeout = "4s"
retries = 0

[[lines.devices]]
name = "kiln"
device = "tc10@4"
poll = "150ms"
parameters = ["set_point"]

[modbus_tcp]
enabled = false

[mqtt]
broker = "mqtt://127.0.0.1:{}"
prefix = "{}"
writes = true
)toml", broker.port(), prefix);
    auto config = parse_gateway_config(text, "plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    GatewayOptions options;
    options.virtual_bus_faults = kiln.injector();
    auto opened = Gateway::open(*config, std::move(options));
    ASSERT_TRUE(opened) << opened.error().message;
    auto gateway = std::move(*opened);
    ASSERT_TRUE(watcher.wait_for(prefix + "/oven/status", "ok"));
    ASSERT_TRUE(watcher.wait_for(prefix + "/kiln/status", "ok"));

    // The kiln stops answering: its line waits out 4 s for each request, and writes to the kiln
    // wait for it, in order.
    kiln.silence();
    ASSERT_TRUE(eventually([&] { return kiln.lost() > 0; })) << "nothing of the kiln's reached its line";
    for (int i = 0; i < 3; ++i) watcher.publish(prefix + "/kiln/set_point/set", std::to_string(100 + i));
    // A write to the oven's line is answered while the kiln's wait.
    watcher.publish(prefix + "/oven/set_point/set", "190");
    const auto oven = watcher.nth(prefix + "/oven/set_point/set/result", 1);
    ASSERT_TRUE(oven) << "the oven's write waited for the kiln's line";
    EXPECT_EQ(nlohmann::json::parse(*oven).at("ok"), true) << *oven;
    EXPECT_EQ(watcher.count(prefix + "/kiln/set_point/set/result"), 0u) << "a kiln write was answered while its line waited";

    // Answering again, the kiln's writes are all answered (written, or failed for the time
    // they waited).
    kiln.answer_again();
    EXPECT_TRUE(watcher.nth(prefix + "/kiln/set_point/set/result", 3)) << "the kiln's writes were not all answered";
}

TEST(MqttBridge, ASetRedeliveredAfterAReconnectIsWrittenOnce) {
    ScriptedBroker broker;
    LogLines lines;
    GatewayOptions options;
    options.log = lines.sink();
    auto gateway = open_gateway(fmt::format("mqtt://127.0.0.1:{}", broker.port()), true, "", std::move(options));
    const std::string set = prefix + "/oven/set_point/set";
    const std::string result = set + "/result";
    // A write the oven's line refuses (measured_value is read-only): it goes through the same
    // line as the sets, after them, so its answer comes after any set taken before it.
    const std::string probe = prefix + "/oven/measured_value/set";

    const std::string probe_result = probe + "/result";
    const std::vector<std::string> results{result, probe_result};

    ASSERT_TRUE(broker.accept(false)) << "the gateway did not connect";
    broker.publish(7, set, "210", false);
    const auto first = broker.published(results);
    ASSERT_TRUE(first) << "no result for the first delivery";
    EXPECT_EQ(first->first, result);
    EXPECT_EQ(nlohmann::json::parse(first->second).at("ok"), true) << first->second;
    broker.drop();  // before the broker saw the PUBACK, as far as the session is concerned

    // The session goes on: the same message again, DUP set. Not written: the probe behind it
    // (a device's writes are taken in order) is the next thing answered.
    ASSERT_TRUE(broker.accept(true)) << "the gateway did not reconnect";
    broker.publish(7, set, "210", true);
    broker.publish(8, probe, "1", false);
    const auto second = broker.published(results);
    ASSERT_TRUE(second) << "no result for the probe";
    EXPECT_EQ(second->first, probe_result) << "the redelivered set was written again: " << second->second;
    EXPECT_TRUE(lines.has("delivered again (message 7)"));

    // The same text in a new message (a new identifier) is a new command, and is written.
    broker.publish(9, set, "210", false);
    const auto third = broker.published(results);
    ASSERT_TRUE(third);
    EXPECT_EQ(third->first, result) << "a new message with the same text was not written";
    broker.drop();

    // A new session (session present 0): the broker numbers afresh, identifier 7 is new.
    ASSERT_TRUE(broker.accept(false)) << "the gateway did not reconnect";
    broker.publish(7, set, "211", false);
    const auto fourth = broker.published(results);
    ASSERT_TRUE(fourth);
    EXPECT_EQ(fourth->first, result) << "a command of a new session was taken for a redelivery";
    EXPECT_EQ(nlohmann::json::parse(fourth->second).at("ok"), true) << fourth->second;
}

// Both fronts on one broker: the Sparkplug node's DCMD writes the set point through
// the device's line, and the MQTT front publishes what the next poll read.
TEST(MqttBridge, TheSparkplugNodeAndTheMqttFrontShareTheBrokerAndTheDevice) {
    REQUIRE_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_topic());
    const std::string url = fmt::format("mqtt://127.0.0.1:{}", broker.port());
    auto gateway = open_gateway(url, false, fmt::format("\n[sparkplug]\nbroker = \"{}\"\ngroup_id = \"plant\"\nwrites = true\n", url));
    const std::string dbirth = "spBv1.0/plant/DBIRTH/loopwire/oven";
    const auto birth_bytes = watcher.nth(dbirth, 1);
    ASSERT_TRUE(birth_bytes) << "no DBIRTH for the oven";
    loopwire::sparkplug::b::Payload birth;
    ASSERT_TRUE(birth.ParseFromString(*birth_bytes));
    std::string set_point;
    for (const auto& metric : birth.metrics()) {
        if (metric.name().ends_with("set_point")) set_point = metric.name();
    }
    ASSERT_FALSE(set_point.empty()) << "the set point is not a metric of the oven's birth";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/measured_value", is_number)) << "the MQTT front publishes beside the node";

    loopwire::sparkplug::b::Payload command;
    auto* metric = command.add_metrics();
    metric->set_name(set_point);
    metric->set_datatype(10);
    metric->set_double_value(135);
    watcher.publish("spBv1.0/plant/DCMD/loopwire/oven", command.SerializeAsString());
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/set_point", [](const std::string& text) { return equals_number(text, 135); }))
        << "the DCMD's write did not reach the device";
}

}  // namespace
}  // namespace loopwire::gateway
