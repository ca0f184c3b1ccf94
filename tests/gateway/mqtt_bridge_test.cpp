// The gateway's MQTT front (gateway/mqtt_bridge.hpp) against a real mosquitto broker that each
// test starts on a free port: an in-process gateway on a simulated line publishes its status and
// values, takes writes and refuses bad ones, and comes back after the broker restarts. A libmosquitto
// client in the test watches the broker as any subscriber would. Skipped without /usr/sbin/mosquitto.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

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
#include "support/profile_test_support.hpp"

extern char** environ;

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

constexpr const char* broker_program = "/usr/sbin/mosquitto";
// Generous: CI runs this under ASan and TSan on two loaded cores.
constexpr auto deadline = 30s;
const std::string prefix = "test/plant1";

const device::ProfileRegistry& profiles() { return device::testing::builtin_registry(); }

// A port nothing listens on now: bound to port 0 and let go. Another process could take it
// before the broker does (a small race, accepted for a test; the broker would then fail to
// start and the test say so).
std::uint16_t free_port() {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) throw std::runtime_error("socket");
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t length = sizeof address;
    if (::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
        ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
        ::close(fd);
        throw std::runtime_error("bind");
    }
    ::close(fd);
    return ntohs(address.sin_port);
}

// A mosquitto broker on 127.0.0.1:port, anonymous, nothing kept on disk.
class Broker {
public:
    explicit Broker(std::uint16_t port) : port_(port) {
        std::string pattern = (fs::temp_directory_path() / "loopwire-mqtt-XXXXXX").string();
        if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp");
        directory_ = pattern;
        std::ofstream(directory_ / "mosquitto.conf") << fmt::format(
            "listener {} 127.0.0.1\nallow_anonymous true\npersistence false\n", port);
        start();
    }
    ~Broker() {
        stop();
        std::error_code ignored;
        fs::remove_all(directory_, ignored);
    }
    Broker(const Broker&) = delete;
    Broker& operator=(const Broker&) = delete;

    void start() {
        const std::string config = (directory_ / "mosquitto.conf").string();
        const std::string log = (directory_ / "broker.log").string();
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
        posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
        std::vector<std::string> words{broker_program, "-c", config};
        std::vector<char*> argv;
        for (auto& word : words) argv.push_back(word.data());
        argv.push_back(nullptr);
        const int rc = posix_spawn(&pid_, broker_program, &actions, nullptr, argv.data(), environ);
        posix_spawn_file_actions_destroy(&actions);
        if (rc != 0) throw std::runtime_error("cannot start mosquitto");
    }
    void stop() {
        if (pid_ <= 0) return;
        ::kill(pid_, SIGKILL);  // as a crash: no goodbye to the clients
        ::waitpid(pid_, nullptr, 0);
        pid_ = -1;
    }
    std::uint16_t port() const { return port_; }

private:
    std::uint16_t port_;
    fs::path directory_;
    pid_t pid_ = -1;
};

struct Message {
    std::string payload;
    bool retained = false;
};

// A subscriber to PREFIX/# that keeps every message, and publishes for the test.
class Watcher {
public:
    explicit Watcher(std::uint16_t port) {
        mosquitto_lib_init();
        client_ = mosquitto_new(nullptr, true, this);
        mosquitto_subscribe_callback_set(client_, [](mosquitto*, void* self, int, int, const int*) {
            auto& watcher = *static_cast<Watcher*>(self);
            std::lock_guard lock(watcher.mutex_);
            watcher.subscribed_ = true;
            watcher.arrived_.notify_all();
        });
        mosquitto_message_callback_set(client_, [](mosquitto*, void* self, const mosquitto_message* message) {
            auto& watcher = *static_cast<Watcher*>(self);
            std::lock_guard lock(watcher.mutex_);
            watcher.messages_[message->topic].push_back(
                {std::string(static_cast<const char*>(message->payload), static_cast<std::size_t>(message->payloadlen)),
                 message->retain});
            watcher.arrived_.notify_all();
        });
        // The broker may still be starting: try until the deadline.
        const auto give_up = std::chrono::steady_clock::now() + deadline;
        while (mosquitto_connect(client_, "127.0.0.1", port, 30) != MOSQ_ERR_SUCCESS) {
            if (std::chrono::steady_clock::now() > give_up) throw std::runtime_error("the broker did not start");
            std::this_thread::sleep_for(50ms);
        }
        // Before the loop's thread starts, and not from a callback: libmosquitto calls those
        // holding a lock that a subscribe or publish there would take out of order.
        if (mosquitto_subscribe(client_, nullptr, (prefix + "/#").c_str(), 1) != MOSQ_ERR_SUCCESS) {
            throw std::runtime_error("cannot subscribe");
        }
        mosquitto_loop_start(client_);
        std::unique_lock lock(mutex_);
        if (!arrived_.wait_for(lock, deadline, [this] { return subscribed_; })) throw std::runtime_error("no SUBACK");
    }
    ~Watcher() {
        mosquitto_disconnect(client_);
        mosquitto_loop_stop(client_, false);
        mosquitto_destroy(client_);
    }
    Watcher(const Watcher&) = delete;
    Watcher& operator=(const Watcher&) = delete;

    void publish(const std::string& topic, const std::string& payload, bool retain = false) {
        ASSERT_EQ(mosquitto_publish(client_, nullptr, topic.c_str(), static_cast<int>(payload.size()), payload.data(), 1, retain),
                  MOSQ_ERR_SUCCESS);
    }

    // The last payload of `topic` once `accept` takes it; nullopt at the deadline.
    std::optional<std::string> wait_for(const std::string& topic, const std::function<bool(const std::string&)>& accept) {
        std::unique_lock lock(mutex_);
        std::optional<std::string> found;
        arrived_.wait_for(lock, deadline, [&] {
            const auto it = messages_.find(topic);
            if (it == messages_.end() || it->second.empty() || !accept(it->second.back().payload)) return false;
            found = it->second.back().payload;
            return true;
        });
        return found;
    }
    std::optional<std::string> wait_for(const std::string& topic, const std::string& payload) {
        return wait_for(topic, [&](const std::string& last) { return last == payload; });
    }
    // The `count`th message of `topic` (from 1), waiting for it.
    std::optional<std::string> nth(const std::string& topic, std::size_t count) {
        std::unique_lock lock(mutex_);
        if (!arrived_.wait_for(lock, deadline, [&] { return messages_[topic].size() >= count; })) return std::nullopt;
        return messages_[topic][count - 1].payload;
    }
    std::size_t count(const std::string& topic) {
        std::lock_guard lock(mutex_);
        return messages_[topic].size();
    }

private:
    mosquitto* client_ = nullptr;
    std::mutex mutex_;
    std::condition_variable arrived_;
    bool subscribed_ = false;
    std::map<std::string, std::vector<Message>> messages_;
};

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

std::unique_ptr<Gateway> open_gateway(std::uint16_t port, bool writes) {
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
parameters = ["measured_value", "set_point"]

[modbus_tcp]
enabled = false

[mqtt]
broker = "mqtt://127.0.0.1:{}"
prefix = "{}"
writes = {}
)toml", port, prefix, writes);
    auto config = parse_gateway_config(text, "plant.toml", profiles());
    if (!config) throw std::runtime_error(config.error().message);
    auto gateway = Gateway::open(*config);
    if (!gateway) throw std::runtime_error(gateway.error().message);
    return std::move(*gateway);
}

#define REQUIRE_BROKER()                                                                  \
    do {                                                                                  \
        if (!fs::exists(broker_program)) GTEST_SKIP() << broker_program << " is not installed (Debian package mosquitto)"; \
    } while (false)

TEST(MqttBridge, PublishesTheGatewayStatusEachDeviceAndItsValues) {
    REQUIRE_BROKER();
    Broker broker(free_port());
    Watcher watcher(broker.port());
    auto gateway = open_gateway(broker.port(), false);

    EXPECT_TRUE(watcher.wait_for(prefix + "/status", "online")) << "no gateway status";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/status", "online")) << "no device status";
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
    EXPECT_EQ(set_point.at("max").at("parameter"), "set_point_high_limit") << *set_point_meta;

    // Writes are off in this gateway: refused, with the reason.
    watcher.publish(prefix + "/oven/set_point/set", "200");
    const auto refused = watcher.nth(prefix + "/oven/set_point/set/result", 1);
    ASSERT_TRUE(refused) << "no answer to a set";
    EXPECT_EQ(nlohmann::json::parse(*refused).at("ok"), false) << *refused;
    EXPECT_NE(refused->find("writes are off"), std::string::npos) << *refused;

    // A clean stop says "offline".
    gateway.reset();
    EXPECT_TRUE(watcher.wait_for(prefix + "/status", "offline")) << "no offline on a clean stop";
}

TEST(MqttBridge, WritesGoToTheDeviceAndBadOnesAreRefused) {
    REQUIRE_BROKER();
    Broker broker(free_port());
    Watcher watcher(broker.port());
    // A command left retained on the broker before the gateway starts: replayed to it on
    // subscription, and ignored.
    watcher.publish(prefix + "/oven/set_point/set", "300", true);
    // Back to the watcher: the broker holds it before the gateway subscribes.
    ASSERT_TRUE(watcher.nth(prefix + "/oven/set_point/set", 1)) << "the retained command did not reach the broker";
    auto gateway = open_gateway(broker.port(), true);
    const std::string value = prefix + "/oven/set_point";
    const std::string result = prefix + "/oven/set_point/set/result";
    ASSERT_TRUE(watcher.wait_for(value, is_number)) << "no set_point value";

    watcher.publish(value + "/set", "200");
    const auto written = watcher.nth(result, 1);
    ASSERT_TRUE(written) << "no answer to a set";
    const auto answer = nlohmann::json::parse(*written);
    EXPECT_EQ(answer.at("ok"), true) << *written;
    EXPECT_EQ(answer.at("value"), "200") << *written;
    EXPECT_TRUE(watcher.wait_for(value, [](const std::string& text) { return equals_number(text, 200); }))
        << "the polls did not read the value written";

    watcher.publish(value + "/set", "99999");
    const auto out_of_range = watcher.nth(result, 2);
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
    std::this_thread::sleep_for(500ms);
    const auto last = watcher.wait_for(value, [](const std::string&) { return true; });
    ASSERT_TRUE(last);
    EXPECT_TRUE(equals_number(*last, 200)) << *last;
    EXPECT_EQ(watcher.count(result), 2u) << "the retained command was answered";
    watcher.publish(prefix + "/oven/set_point/set", "", true);  // clears the retained command
}

TEST(MqttBridge, ComesBackWhenTheBrokerRestarts) {
    REQUIRE_BROKER();
    Broker broker(free_port());
    auto gateway = open_gateway(broker.port(), false);
    {
        Watcher watcher(broker.port());
        ASSERT_TRUE(watcher.wait_for(prefix + "/status", "online"));
        ASSERT_TRUE(watcher.wait_for(prefix + "/oven/measured_value", is_number));
    }
    broker.stop();
    std::this_thread::sleep_for(300ms);
    broker.start();  // the same port; it kept nothing of before
    Watcher watcher(broker.port());
    EXPECT_TRUE(watcher.wait_for(prefix + "/status", "online")) << "the gateway did not reconnect";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/status", "online")) << "the device status was not republished";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/measured_value", is_number)) << "the values were not republished";
}

TEST(MqttBridge, AGatewayStartsWithoutItsBroker) {
    REQUIRE_BROKER();
    const std::uint16_t port = free_port();
    auto gateway = open_gateway(port, false);  // nothing listens there yet: not an error
    std::this_thread::sleep_for(300ms);
    Broker broker(port);
    Watcher watcher(port);
    EXPECT_TRUE(watcher.wait_for(prefix + "/status", "online")) << "the gateway did not connect once the broker came";
    EXPECT_TRUE(watcher.wait_for(prefix + "/oven/measured_value", is_number));
}

}  // namespace
}  // namespace loopwire::gateway
