#include "gateway/mqtt_bridge.hpp"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string_view>
#include <stop_token>
#include <thread>

#include <fmt/format.h>
#include <mosquitto.h>
#include <nlohmann/json.hpp>


namespace loopwire::gateway {
namespace {

constexpr int keepalive_seconds = 30;
constexpr int qos_at_least_once = 1;
// How long one turn of the network loop waits for the socket: also the longest a queued
// publication waits before it is sent.
constexpr int loop_timeout_ms = 50;

void init_library_once() {
    static std::once_flag once;
    // Never cleaned up: other clients in the process may still use the library at exit.
    std::call_once(once, [] { mosquitto_lib_init(); });
}

// The configuration restricts names to these (gateway_config.cpp, checked_name): a name is one
// topic level, with no '/', '+' or '#' to escape.
[[maybe_unused]] bool topic_level(const std::string& name) {
    return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '_';
    });
}

std::string device_status_word(const std::string& status) {
    if (status == "ok") return "online";
    if (status == "no-reply") return "offline";
    if (status == "partial") return "error";
    return status;
}

nlohmann::json bound_json(const device::Bound& bound) {
    if (const auto* number = std::get_if<double>(&bound)) return *number;
    return nlohmann::json{{"parameter", std::get<std::string>(bound)}};
}

struct Publication {
    std::string topic;
    std::string payload;
    bool retained = true;
    int qos = 0;
};

struct WriteCommand {
    std::string device;
    std::string parameter;
    std::string text;
};

}  // namespace

struct MqttBridge::State {
    MqttConfig config;
    MqttTiming timing;
    GatewayLog log;
    const DeviceWriter* writer = nullptr;

    mosquitto* client = nullptr;
    std::atomic<bool> is_connected{false};

    std::mutex mutex;  // guards the two queues
    std::condition_variable_any commands_arrived;
    std::deque<Publication> outgoing;  // from the value stream and the writes
    std::deque<WriteCommand> commands;  // from the broker, for the worker

    // The network thread's own: every retained topic's payload, republished on each connection.
    std::map<std::string, std::string> retained;
    bool told_unreachable = false;
    bool just_connected = false;  // set by on_connect, acted on by the network loop

    std::jthread worker;
    std::jthread network;
    ValueSubscription subscription;

    void say(const std::string& message) const {
        if (log) log("mqtt " + config.broker + ": " + message);
    }

    std::string topic(const std::string& device, const std::string& parameter = {}) const {
        return parameter.empty() ? fmt::format("{}/{}", config.prefix, device)
                                 : fmt::format("{}/{}/{}", config.prefix, device, parameter);
    }

    void queue(Publication publication) {
        std::lock_guard lock(mutex);
        outgoing.push_back(std::move(publication));
    }

    // On a poll thread: turns the change into its topics and queues them, nothing more.
    void on_change(const ValueChange& change) {
        assert(topic_level(change.device) && (change.about_device() || topic_level(change.parameter)));
        if (change.about_device()) {
            queue({topic(change.device, "status"), device_status_word(change.status), true, qos_at_least_once});
            return;
        }
        const std::string base = topic(change.device, change.parameter);
        nlohmann::json meta{{"unit", change.unit}, {"status", change.status}, {"error", change.error}};
        if (const WritableDevice* device = writer->find(change.device)) {
            if (const device::Parameter* parameter = device->address.profile->find(change.parameter)) {
                meta["writable"] = parameter->writable;
                if (parameter->min) meta["min"] = bound_json(*parameter->min);
                if (parameter->max) meta["max"] = bound_json(*parameter->max);
            }
        }
        std::lock_guard lock(mutex);
        outgoing.push_back({base, change.value ? change.text : change.status, true, 0});
        outgoing.push_back({base + "/meta", meta.dump(), true, 0});
    }

    // --- the network thread ---------------------------------------------------------------------

    void publish(const Publication& publication) {
        // A failure (the connection just broke) loses nothing retained: all of it is sent again
        // on the next connection.
        (void)mosquitto_publish(client, nullptr, publication.topic.c_str(), static_cast<int>(publication.payload.size()),
                                publication.payload.data(), publication.qos, publication.retained);
    }

    void send_queued() {
        std::deque<Publication> batch;
        {
            std::lock_guard lock(mutex);
            batch.swap(outgoing);
        }
        for (auto& publication : batch) {
            if (publication.retained) {
                auto& last = retained[publication.topic];
                if (last == publication.payload) continue;  // a meta or status that did not change
                last = publication.payload;
            }
            if (is_connected.load()) publish(publication);
        }
    }

    // In mosquitto_loop, holding libmosquitto's callback lock: only notes the connection.
    // Publishing from here would take the client's other locks in the opposite order to a
    // publish outside a callback (ThreadSanitizer reports the inversion); announce() does it.
    void on_connect(int code) {
        if (code != 0) {
            say(fmt::format("the broker refused the connection: {}", mosquitto_connack_string(code)));
            return;
        }
        just_connected = true;
    }

    // After a connection was made: the gateway's status, the commands' subscription, and every
    // retained topic again (the broker may have lost them, or this is its first connection).
    void announce() {
        send_queued();  // not connected yet: brings the retained picture up to date, sends nothing
        is_connected.store(true);
        told_unreachable = false;
        say("connected");
        const std::string status = config.prefix + "/status";
        publish({status, "online", true, qos_at_least_once});
        const std::string commands_topic = config.prefix + "/+/+/set";
        (void)mosquitto_subscribe(client, nullptr, commands_topic.c_str(), qos_at_least_once);
        for (const auto& [topic, payload] : retained) publish({topic, payload, true, 0});
    }

    void on_message(const mosquitto_message& message) {
        // A retained command is one the broker replays at every (re)subscription: applying it
        // would write the same value again after each reconnect. Only live commands count.
        if (message.retain) return;
        const std::string topic = message.topic;
        const std::string head = config.prefix + "/";
        if (topic.rfind(head, 0) != 0) return;
        const std::string rest = topic.substr(head.size());  // DEVICE/PARAMETER/set
        const auto first = rest.find('/');
        const auto second = first == std::string::npos ? first : rest.find('/', first + 1);
        if (second == std::string::npos || rest.substr(second) != "/set") return;
        WriteCommand command{rest.substr(0, first), rest.substr(first + 1, second - first - 1),
                             std::string(static_cast<const char*>(message.payload),
                                         static_cast<std::size_t>(std::max(message.payloadlen, 0)))};
        std::lock_guard lock(mutex);
        commands.push_back(std::move(command));
        commands_arrived.notify_all();
    }

    // Sleeps `delay`, or less when stopped.
    static void pause(const std::stop_token& stop, std::chrono::milliseconds delay) {
        std::mutex m;
        std::condition_variable_any woken;
        std::unique_lock lock(m);
        woken.wait_for(lock, stop, delay, [] { return false; });
    }

    void run_network(const std::stop_token& stop) {
        bool have_socket = false;
        auto delay = timing.reconnect_first;
        while (!stop.stop_requested()) {
            if (!have_socket) {
                const int rc = mosquitto_connect(client, config.host.c_str(), config.port, keepalive_seconds);
                if (rc != MOSQ_ERR_SUCCESS) {
                    if (!std::exchange(told_unreachable, true)) {
                        say(fmt::format("cannot reach the broker ({}); retrying in the background",
                                        rc == MOSQ_ERR_ERRNO ? std::string(std::strerror(errno)) : mosquitto_strerror(rc)));
                    }
                    send_queued();  // keeps the retained picture current, and the queue short
                    pause(stop, delay);
                    delay = std::min(delay * 2, timing.reconnect_last);
                    continue;
                }
                have_socket = true;
            }
            send_queued();
            const int rc = mosquitto_loop(client, loop_timeout_ms, 1);
            if (std::exchange(just_connected, false)) {
                announce();
                delay = timing.reconnect_first;
            }
            if (rc != MOSQ_ERR_SUCCESS) {
                if (is_connected.exchange(false)) say(fmt::format("connection lost ({})", mosquitto_strerror(rc)));
                have_socket = false;
                told_unreachable = false;
                pause(stop, delay);
                delay = std::min(delay * 2, timing.reconnect_last);
            }
        }
        if (!have_socket || !is_connected.load()) return;
        // A clean disconnect does not fire the will: say so ourselves, then give the broker a
        // moment to take it.
        send_queued();
        publish({config.prefix + "/status", "offline", true, qos_at_least_once});
        (void)mosquitto_disconnect(client);
        const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
        while (std::chrono::steady_clock::now() < give_up &&
               mosquitto_loop(client, loop_timeout_ms, 1) == MOSQ_ERR_SUCCESS) {
        }
        is_connected.store(false);
    }

    // --- the worker thread ----------------------------------------------------------------------

    void execute(const WriteCommand& command) {
        nlohmann::json result;
        std::string error;
        if (!config.writes) {
            error = "writes are off ([mqtt] writes = false)";
        } else if (auto written = writer->write(command.device, {{command.parameter, command.text}}); !written) {
            error = written.error().message;
        }
        if (error.empty()) {
            result = {{"ok", true}, {"value", command.text}};
            say(fmt::format("{}.{} = {} written", command.device, command.parameter, command.text));
        } else {
            result = {{"ok", false}, {"error", error}};
            say(fmt::format("{}.{} = {} refused: {}", command.device, command.parameter, command.text, error));
        }
        queue({fmt::format("{}/{}/{}/set/result", config.prefix, command.device, command.parameter), result.dump(), false,
               qos_at_least_once});
    }

    void run_worker(const std::stop_token& stop) {
        for (;;) {
            WriteCommand command;
            {
                std::unique_lock lock(mutex);
                if (!commands_arrived.wait(lock, stop, [this] { return !commands.empty(); })) return;
                command = std::move(commands.front());
                commands.pop_front();
            }
            execute(command);
        }
    }
};

MqttBridge::MqttBridge(MqttConfig config, const DeviceWriter& writer, ValueCache& cache, GatewayLog log, MqttTiming timing)
    : state_(std::make_unique<State>()) {
    init_library_once();
    State& s = *state_;
    s.config = std::move(config);
    s.timing = timing;
    s.log = std::move(log);
    s.writer = &writer;
    const std::string id = s.config.client_id.empty() ? "loopwire-" + s.config.prefix : s.config.client_id;
    s.client = mosquitto_new(id.c_str(), true, &s);
    if (!s.client) throw std::bad_alloc();
    // Called on the network thread, inside mosquitto_loop.
    mosquitto_connect_callback_set(s.client, [](mosquitto*, void* state, int code) {
        static_cast<State*>(state)->on_connect(code);
    });
    mosquitto_message_callback_set(s.client, [](mosquitto*, void* state, const mosquitto_message* message) {
        if (message) static_cast<State*>(state)->on_message(*message);
    });
    const std::string status = s.config.prefix + "/status";
    constexpr std::string_view offline = "offline";
    (void)mosquitto_will_set(s.client, status.c_str(), static_cast<int>(offline.size()), offline.data(), qos_at_least_once,
                             true);
    s.worker = std::jthread([&s](std::stop_token stop) { s.run_worker(stop); });
    s.network = std::jthread([&s](std::stop_token stop) { s.run_network(stop); });
    s.subscription = cache.subscribe([&s](const ValueChange& change) { s.on_change(change); });
}

MqttBridge::~MqttBridge() {
    State& s = *state_;
    s.subscription.reset();
    s.worker.request_stop();
    s.worker.join();  // a write under way finishes first: its result is still published
    s.network.request_stop();
    s.network.join();
    mosquitto_destroy(s.client);
}

bool MqttBridge::connected() const { return state_->is_connected.load(); }

}  // namespace loopwire::gateway
