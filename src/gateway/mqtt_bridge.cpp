#include "gateway/mqtt_bridge.hpp"

#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <set>
#include <string_view>
#include <stop_token>

#include <fmt/format.h>
#include <mosquitto.h>
#include <nlohmann/json.hpp>

#include "client/device_status.hpp"
#include "common/fnv1a.hpp"
#include "common/peer_text.hpp"
#include "gateway/mqtt_client.hpp"
#include "gateway/mqtt_commands.hpp"
#include "gateway/mqtt_loop_driver.hpp"
#include "gateway/mqtt_documents.hpp"


namespace loopwire::gateway {
namespace {

// A batch of publications leaves in as few TCP segments as it fills (tcp(7), TCP_CORK): on an
// external loop libmosquitto writes each message the moment it is published, and the broker
// and the subscribers then read, and wake, once per small segment. Uncorked at the end of the
// batch, so nothing waits for more. -1: nothing to do (not connected, or one message).
class CorkedSocket {
public:
    explicit CorkedSocket(int fd) : fd_(fd) { set(1); }
    ~CorkedSocket() { set(0); }
    CorkedSocket(const CorkedSocket&) = delete;
    CorkedSocket& operator=(const CorkedSocket&) = delete;

private:
    void set(int on) const {
        if (fd_ >= 0) (void)::setsockopt(fd_, IPPROTO_TCP, TCP_CORK, &on, sizeof on);
    }
    int fd_;
};

constexpr int keepalive_seconds = 30;
constexpr int qos_at_least_once = 1;
// The shutdown's turns, while the last "offline" messages go out.
constexpr int goodbye_turn_ms = 50;

// The configuration restricts names to these (gateway_config.cpp, checked_name): a name is one
// topic level, with no '/', '+' or '#' to escape.
[[maybe_unused]] bool topic_level(const std::string& name) {
    return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '_';
    });
}

// The one place MQTT maps a device's status. PREFIX/DEVICE/status carries its word, as every
// front says it (client/device_status.hpp: "ok", "partial", "no-reply", "line-down", "stale",
// "wrong-device"); PREFIX/DEVICE/availability what Home Assistant's availability reads:
// "online" while its values are the device's and current (ok, partial), "offline" otherwise.
// "waiting" is never published: a device skipped in back-off keeps its last word.
constexpr std::string_view available = "online";
constexpr std::string_view unavailable = "offline";

std::string availability_word(device::DeviceStatus status) {
    return std::string(device::answered(status) ? available : unavailable);
}

struct Publication {
    std::string topic;
    std::string payload;
    bool retained = true;
    int qos = 0;
    bool periodic = false;  // a value: published again every `republish` interval
};

// What the broker sent last on a retained topic, and whether it is a value.
struct RetainedTopic {
    std::string payload;
    bool periodic = false;
};

// A QoS 1 command already taken in this session. The broker numbers its messages to a client
// with packet identifiers it does not reuse until they are acknowledged; a message redelivered
// after a reconnect (MQTT 3.1.1, 4.4: the DUP flag) carries the same identifier, topic and
// payload. libmosquitto acknowledges and passes on every copy (it does not expose the DUP flag),
// so the bridge remembers the last ones: by identifier and a hash of topic and payload, so that
// what is remembered stays small whatever the publishers send.
struct TakenCommand {
    int mid = 0;
    std::uint64_t digest = 0;
    bool operator==(const TakenCommand&) const = default;
};
constexpr std::size_t remembered_commands = 1024;

// FNV-1a over the topic, a separator no topic holds, and the payload.
std::uint64_t command_digest(std::string_view topic, std::string_view payload) {
    return fnv1a(payload, fnv1a(std::string_view("\0", 1), fnv1a(topic)));
}

}  // namespace

struct MqttBridge::State {
    MqttConfig config;
    MqttTiming timing;
    GatewayLog log;
    const DeviceWriter* writer = nullptr;

    mosquitto* client = nullptr;
    std::atomic<bool> is_connected{false};

    std::mutex mutex;  // guards the queue and what the polls said about the devices
    std::deque<Publication> outgoing;  // from the value stream and the writes' results
    std::map<std::string, DeviceSeen> devices;  // by configured name
    // Every device of the configuration, whether or not its polls have said anything yet: a stop
    // says each of them "offline", or a stop just after a reload, before the first poll, would
    // leave the previous round's retained "online" standing.
    std::vector<std::string> configured_devices;
    // The poll threads' own (one subscriber's callbacks never overlap): each parameter's last
    // error, and what was announced to Home Assistant: each parameter's unit and decimals (by
    // its state topic), each device's control loop.
    std::map<std::string, std::string> last_errors;
    std::map<std::string, std::string> meta_inputs_of;  // per value topic: what its meta was last made of
    std::map<std::string, std::string> discovered;
    struct LoopSeen {
        std::optional<std::string> pv_unit;
        std::optional<int> sp_decimals;
        bool mode_polled = false;
        bool out_polled = false;
        device::ValueLimits sp_limits;
        std::optional<ControlLoopSample> announced;
    };
    std::map<std::string, LoopSeen> loops;

    // The network's own (the loop's; after the driver stopped, the destructor's): every retained
    // topic's payload, republished on each connection.
    std::unordered_map<std::string, RetainedTopic> retained;
    std::deque<TakenCommand> taken;  // the last commands of this session, oldest first
    bool told_unreachable = false;
    bool told_no_handshake = false;  // until a connection is accepted
    bool told_refused = false;
    bool just_connected = false;  // set by on_connect, acted on after the turn
    // The QoS 1 publications of this connection the broker has not acknowledged yet.
    std::set<int> unacknowledged;
    std::chrono::steady_clock::time_point next_republish{};

    // Set by hand_over (guarded by `mutex`): what stays "online" when the bridge closes for a
    // reload rather than a stop.
    bool gateway_continues = false;
    std::set<std::string> continuing_devices;

    // The sweep (mqtt_bridge.hpp): the network's own. Once per bridge, at its first connection
    // (again on the next one when that connection broke before it ended).
    PublishedParameters published;
    struct Sweep {
        bool done = false;
        int awaited = -1;  // the message id of the last subscription's SUBACK
        std::optional<std::chrono::steady_clock::time_point> ends;  // set at that SUBACK
        std::set<std::string> found;  // this gateway's retained topics seen meanwhile
    } sweep;

    std::unique_ptr<MqttCommands> commands;  // the writes from the broker; before the driver
    std::unique_ptr<mqtt::LoopDriver> driver;  // the network, on the loop
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
        queue_locked(std::move(publication));
    }

    // With `mutex` held. The network sends the whole queue when woken, so only the first
    // publication of a batch needs to wake it.
    void queue_locked(Publication publication) {
        if (outgoing.empty() && driver) driver->wake();
        outgoing.push_back(std::move(publication));
    }

    // On a poll thread: turns the change into its topics and queues them, nothing more.
    void on_change(const ValueChange& change) {
        assert(topic_level(change.device) && (change.about_device() || topic_level(change.parameter)));
        if (change.about_device()) {
            std::lock_guard lock(mutex);
            devices[change.device] = {change.device_status, change.error};
            queue_locked({topic(change.device, "status"), std::string(device::status_text(change.device_status)), true,
                          qos_at_least_once});
            queue_locked({topic(change.device, "availability"), availability_word(change.device_status), true,
                          qos_at_least_once});
            return;
        }
        const std::string base = topic(change.device, change.parameter);
        const WritableDevice* device = writer->find(change.device);
        const device::Parameter* parameter = device ? device->address.profile->find(change.parameter) : nullptr;
        std::string& last_error = last_errors[base];
        if (!change.error.empty()) last_error = change.error;
        // Built only when something in it changed: a new value alone leaves it as it was.
        std::string& meta_made_of = meta_inputs_of[base];
        std::string inputs = meta_inputs(change, parameter, last_error);
        std::optional<std::string> meta;
        if (inputs != meta_made_of) {
            meta = json_text(meta_document(change, parameter, last_error));
            meta_made_of = std::move(inputs);
        }
        std::vector<DiscoveryDocument> discoveries;
        if (config.discovery == MqttConfig::Discovery::homeassistant && parameter) {
            discoveries = discover(change, base, *device->address.profile, *parameter);
        }
        std::lock_guard lock(mutex);
        queue_locked({base, change.value ? change.text : change.status, true, 0, true});
        // A device's texts (an error, an enum label) are its own and may not be valid UTF-8.
        if (meta) queue_locked({base + "/meta", std::move(*meta), true, 0});
        for (const auto& discovery : discoveries) {
            const std::string payload = discovery.config.is_null() ? std::string() : json_text(discovery.config);
            queue_locked({discovery.topic, payload, true, qos_at_least_once});
        }
    }

    // The discovery documents a change calls for: the parameter's when it is first seen and
    // again when its unit, decimals or limits change on the device (°C to °F, the decimal point
    // moved, SP.HL lowered),
    // the device's control loop once its PV and SP have values and whenever those change (and
    // once more when its mode word first has one).
    std::vector<DiscoveryDocument> discover(const ValueChange& change, const std::string& base, const device::Profile& profile,
                                            const device::Parameter& parameter) {
        std::vector<DiscoveryDocument> documents;
        const ValueChange* latest = change.value ? &change : nullptr;
        const auto limit = [](const std::optional<double>& value) { return value ? fmt::format("{}", *value) : std::string(); };
        const std::string said = latest ? fmt::format("{}|{}|{}|{}", change.unit, shown_decimals(parameter, latest),
                                                      limit(change.limits.min), limit(change.limits.max))
                                        : std::string();
        const auto announced = discovered.find(base);
        if (announced == discovered.end() || (latest && announced->second != said)) {
            // A bit field's bits need no unit: announced once, with the field.
            if (announced == discovered.end()) documents = bit_documents(config, change.device, profile, parameter);
            discovered[base] = said;
            documents.push_back(discovery_document(config, change.device, profile, parameter, latest));
        }
        if (!latest) return documents;
        const ControlLoop loop = control_loop_of(profile);
        if (&parameter != loop.pv && &parameter != loop.sp && &parameter != loop.mode && &parameter != loop.out) return documents;
        LoopSeen& seen = loops[change.device];
        if (&parameter == loop.pv) seen.pv_unit = change.unit;
        if (&parameter == loop.sp) {
            seen.sp_decimals = shown_decimals(parameter, latest);
            seen.sp_limits = change.limits;
        }
        if (&parameter == loop.mode) seen.mode_polled = true;
        if (&parameter == loop.out) seen.out_polled = true;
        if (!seen.pv_unit || !seen.sp_decimals) return documents;
        const ControlLoopSample sample{*seen.pv_unit, *seen.sp_decimals, seen.mode_polled, seen.out_polled, seen.sp_limits};
        if (seen.announced == sample) return documents;
        auto climate = climate_document(config, change.device, profile, sample);
        const bool was_climate = seen.announced && climate_document(config, change.device, profile, *seen.announced);
        seen.announced = sample;
        if (climate) {
            documents.push_back(std::move(*climate));
        } else if (was_climate) {
            documents.push_back({climate_topic(config, change.device), nullptr});
        }
        return documents;
    }

    // --- the network (on the loop, mqtt_loop_driver.hpp) -----------------------------------------

    void publish(const Publication& publication) {
        // A failure (the connection just broke) loses nothing retained: all of it is sent again
        // on the next connection.
        int mid = 0;
        const int rc = mosquitto_publish(client, &mid, publication.topic.c_str(), static_cast<int>(publication.payload.size()),
                                         publication.payload.data(), publication.qos, publication.retained);
        if (rc == MOSQ_ERR_SUCCESS && publication.qos > 0) unacknowledged.insert(mid);
    }

    // Sends what was queued. While the broker is away only the retained picture is brought up
    // to date: the last value of each topic wins, and goes out on the next connection.
    void send_queued() {
        std::deque<Publication> batch;
        {
            std::lock_guard lock(mutex);
            batch.swap(outgoing);
        }
        const CorkedSocket corked(batch.size() > 1 && is_connected.load() ? mosquitto_socket(client) : -1);
        for (auto& publication : batch) {
            if (publication.retained) {
                auto& last = retained[publication.topic];
                // A meta or status that did not change; a value the polls found again unchanged
                // never arrives here (the value cache only passes changes).
                if (last.payload == publication.payload && !publication.periodic) continue;
                last = {publication.payload, publication.periodic};
            }
            if (is_connected.load()) publish(publication);
        }
    }

    // Every value again, at least once per `republish`: a subscriber that missed a retained
    // message, or a broker that lost it, catches up without waiting for a change.
    void republish_when_due() {
        if (!config.republish || !is_connected.load()) return;
        const auto now = std::chrono::steady_clock::now();
        if (now < next_republish) return;
        next_republish = now + *config.republish;
        for (const auto& [name, topic_state] : retained) {
            if (topic_state.periodic) publish({name, topic_state.payload, true, 0});
        }
    }

    // In mosquitto_loop, holding libmosquitto's callback lock: only notes the connection.
    // Publishing from here would take the client's other locks in the opposite order to a
    // publish outside a callback (ThreadSanitizer reports the inversion); announce() does it.
    void on_connect(int code, int flags) {
        if (code != 0) {
            // Said once until a connection succeeds; the loop keeps trying with back-off (the
            // broker's password file may be fixed meanwhile).
            if (!std::exchange(told_refused, true)) {
                say(fmt::format("the broker refused the connection: {}; retrying in the background",
                                mosquitto_connack_string(code)));
            }
            return;
        }
        // CONNACK's session-present flag (MQTT 3.1.1, 3.2.2.2): a new session cannot redeliver
        // anything, and the broker numbers its messages afresh.
        if ((flags & 1) == 0) taken.clear();
        just_connected = true;
    }

    // After a connection was made: the gateway's status, the commands' subscription, and every
    // retained topic again (the broker may have lost them, or this is its first connection).
    void announce() {
        send_queued();  // not connected yet: brings the retained picture up to date, sends nothing
        is_connected.store(true);
        told_unreachable = false;
        told_refused = false;
        told_no_handshake = false;
        say("connected");
        const std::string status = config.prefix + "/status";
        publish({status, "online", true, qos_at_least_once});
        const std::string commands_topic = config.prefix + "/+/+/set";
        (void)mosquitto_subscribe(client, nullptr, commands_topic.c_str(), qos_at_least_once);
        for (const auto& [name, topic_state] : retained) publish({name, topic_state.payload, true, 0});
        start_sweep();
        if (config.republish) next_republish = std::chrono::steady_clock::now() + *config.republish;
    }

    // --- the sweep ---------------------------------------------------------------------------

    std::vector<std::string> sweep_subscriptions() const {
        return {config.discovery_prefix + "/+/+/config", config.prefix + "/+/+", config.prefix + "/+/+/meta"};
    }

    void start_sweep() {
        if (sweep.done) return;
        sweep.ends.reset();
        sweep.found.clear();
        for (const auto& pattern : sweep_subscriptions()) {
            (void)mosquitto_subscribe(client, &sweep.awaited, pattern.c_str(), qos_at_least_once);
        }
    }

    // In mosquitto_loop (libmosquitto's callback): only notes the time.
    void on_subscribed(int mid) {
        if (!sweep.done && mid == sweep.awaited) sweep.ends = std::chrono::steady_clock::now() + timing.sweep_window;
    }

    // Whether a retained discovery document is this gateway's: its availability, or its state
    // (the gateway's own entity), is this gateway's status topic. Another gateway's documents,
    // or another program's, are never touched.
    bool own_discovery(std::string_view payload) const {
        constexpr std::size_t largest_document = 64 * 1024;
        if (payload.size() > largest_document) return false;
        const auto document = nlohmann::json::parse(payload, nullptr, false);
        if (!document.is_object()) return false;
        const std::string status = config.prefix + "/status";
        if (document.value("state_topic", nlohmann::json()) == status) return true;
        const auto availability = document.find("availability");
        if (availability == document.end() || !availability->is_array()) return false;
        return std::any_of(availability->begin(), availability->end(), [&](const nlohmann::json& entry) {
            return entry.is_object() && entry.value("topic", nlohmann::json()) == status;
        });
    }

    void note_retained(const mosquitto_message& message, std::string_view topic, std::string_view payload) {
        constexpr std::size_t most_topics = 100000;  // whatever the broker holds, memory stays bounded
        if (sweep.done || !message.retain || payload.empty() || sweep.found.size() >= most_topics) return;
        const bool discovery = topic.starts_with(config.discovery_prefix + "/") && topic.ends_with("/config");
        if (discovery ? own_discovery(payload) : topic.starts_with(config.prefix + "/")) sweep.found.emplace(topic);
    }

    // Every topic the configuration publishes, whether or not it has been published yet: the
    // gateway's and each device's status topics, each published parameter's value and meta, and
    // with discovery their documents (whose topics depend on the parameter, not on its value).
    std::set<std::string> configured_topics() const {
        std::set<std::string> topics{config.prefix + "/status"};
        const bool discovering = config.discovery == MqttConfig::Discovery::homeassistant;
        if (discovering) topics.insert(gateway_document(config).topic);
        for (const auto& name : configured_devices) {
            topics.insert(topic(name, "status"));
            topics.insert(topic(name, "availability"));
            const WritableDevice* device = writer->find(name);
            if (!device) continue;
            const device::Profile& profile = *device->address.profile;
            const auto listed = published.find(name);
            for (const auto& parameter : profile.parameters) {
                if (listed != published.end() && !listed->second.contains(parameter.name)) continue;
                topics.insert(topic(name, parameter.name));
                topics.insert(topic(name, parameter.name) + "/meta");
                if (!discovering) continue;
                topics.insert(discovery_document(config, name, profile, parameter).topic);
                for (const auto& bit : bit_documents(config, name, profile, parameter)) topics.insert(bit.topic);
            }
            if (discovering) topics.insert(climate_topic(config, name));
        }
        return topics;
    }

    // On a turn: once the window has passed, clears what was found and is no longer configured.
    void finish_sweep_when_due() {
        if (sweep.done || !sweep.ends || std::chrono::steady_clock::now() < *sweep.ends || !is_connected.load()) return;
        sweep.done = true;
        for (const auto& pattern : sweep_subscriptions()) (void)mosquitto_unsubscribe(client, nullptr, pattern.c_str());
        const std::set<std::string> keep = configured_topics();
        std::size_t cleared = 0;
        for (const auto& found : sweep.found) {
            if (keep.contains(found)) continue;
            const auto published_now = retained.find(found);
            if (published_now != retained.end() && !published_now->second.payload.empty()) continue;
            retained.erase(found);
            publish({found, std::string(), true, qos_at_least_once});
            ++cleared;
        }
        if (cleared > 0) say(fmt::format("cleared {} retained topic{} the configuration no longer publishes", cleared, cleared == 1 ? "" : "s"));
        sweep.found.clear();
    }

    // Whether the command is a copy of one taken earlier in this session; remembers it if not.
    bool redelivered(const mosquitto_message& message, std::string_view topic, std::string_view payload) {
        if (message.qos == 0) return false;  // QoS 0 has no identifier and is never sent twice
        const TakenCommand command{message.mid, command_digest(topic, payload)};
        if (std::find(taken.begin(), taken.end(), command) != taken.end()) return true;
        taken.push_back(command);
        if (taken.size() > remembered_commands) taken.pop_front();
        return false;
    }

    // On the loop: never blocks (MqttCommands hands each write to its line).
    void on_message(const mosquitto_message& message) {
        if (!message.topic) return;
        const std::string_view topic = message.topic;
        const std::string_view payload(static_cast<const char*>(message.payload),
                                       static_cast<std::size_t>(std::max(message.payloadlen, 0)));
        if (!command_topic(config.prefix, topic)) return note_retained(message, topic, payload);
        // A retained command is one the broker replays at every (re)subscription: applying it
        // would write the same value again after each reconnect. It is refused, and said so on
        // its result topic, as the Sparkplug node refuses a retained DCMD.
        if (message.retain) return commands->refuse_retained(topic, payload);
        if (redelivered(message, topic, payload)) {
            say(fmt::format("{} = {} delivered again (message {}): already taken, not written twice", quoted_excerpt(topic),
                            quoted_excerpt(payload), message.mid));
            return;
        }
        commands->take(topic, payload);
    }

    // The driver's hooks: what the bridge does around each turn of the network work.

    mqtt::LoopDriver::Hooks network_hooks() {
        mqtt::LoopDriver::Hooks hooks;
        hooks.connect = [this] { return mosquitto_connect_async(client, config.host.c_str(), config.port, keepalive_seconds); };
        hooks.unreachable = [this](const std::string& why) {
            if (!std::exchange(told_unreachable, true)) say(fmt::format("cannot reach the broker ({}); retrying in the background", why));
            send_queued();  // keeps the retained picture current, and the queue short
        };
        hooks.turned = [this] {
            send_queued();
            republish_when_due();
            finish_sweep_when_due();
            if (!std::exchange(just_connected, false)) return false;
            announce();
            return true;
        };
        hooks.lost = [this](const std::string& why) {
            if (is_connected.exchange(false)) {
                say(fmt::format("connection lost ({})", why));
            } else if (!std::exchange(told_no_handshake, true)) {
                say(mqtt::handshake_failure(why));
            }
            unacknowledged.clear();  // libmosquitto sends them again on the next connection
            told_unreachable = false;
        };
        return hooks;
    }

    // A clean disconnect does not fire the will: the gateway and each of its devices say
    // "offline" themselves (but what a reload hands over), then the broker gets a moment to take it.
    void say_goodbye() {
        send_queued();
        std::set<std::string> names;
        bool gateway_stays = false;
        {
            std::lock_guard lock(mutex);
            for (const auto& name : configured_devices) {
                if (!continuing_devices.contains(name)) names.insert(name);
            }
            for (const auto& [name, seen] : devices) {
                if (!continuing_devices.contains(name)) names.insert(name);
            }
            gateway_stays = gateway_continues;
        }
        // Nobody polls them from now on: unavailable, and not polled ("waiting") rather than the
        // last word, which would stand retained as if it were still true.
        for (const auto& name : names) {
            publish({topic(name, "availability"), std::string(unavailable), true, qos_at_least_once});
            publish({topic(name, "status"), std::string(device::status_text(device::DeviceStatus::waiting)), true,
                     qos_at_least_once});
        }
        if (!gateway_stays) publish({config.prefix + "/status", std::string(unavailable), true, qos_at_least_once});
        // Disconnecting before the broker has acknowledged a QoS 1 publication makes its PUBACK
        // fail on a closed socket: mosquitto then takes the disconnection for a broken one
        // ("disconnected due to out of memory", eclipse-mosquitto/mosquitto#2627) and publishes
        // the will, "offline", which a reload must not do. So the acknowledgements come first.
        const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
        while (!unacknowledged.empty() && std::chrono::steady_clock::now() < give_up &&
               mosquitto_loop(client, goodbye_turn_ms, 1) == MOSQ_ERR_SUCCESS) {
        }
        (void)mosquitto_disconnect(client);
        while (std::chrono::steady_clock::now() < give_up &&
               mosquitto_loop(client, goodbye_turn_ms, 1) == MOSQ_ERR_SUCCESS) {
        }
        is_connected.store(false);
    }
};

MqttBridge::MqttBridge(MqttConfig config, const DeviceWriter& writer, ValueCache& cache, GatewayLog log, MqttTiming timing,
                       boost::asio::io_context* loop, PublishedParameters published)
    : state_(std::make_unique<State>()) {
    mqtt::init_library_once();
    State& s = *state_;
    s.config = std::move(config);
    s.timing = timing;
    s.published = std::move(published);
    s.log = std::move(log);
    s.writer = &writer;
    s.configured_devices = writer.device_names();
    const std::string id = s.config.client_id.empty() ? "loopwire-" + s.config.prefix : s.config.client_id;
    // A persistent session (clean session off, MQTT 3.1.1, 3.1.2.4): the broker keeps the
    // subscription and the QoS 1 commands sent while the connection is down, and redelivers the
    // ones not yet acknowledged; on_message takes each only once.
    s.client = mosquitto_new(id.c_str(), false, &s);
    if (!s.client) throw std::bad_alloc();
    mqtt::send_without_delay(s.client);
    mqtt::configure_security(s.client, s.config.tls, s.config.username, s.config.password,
                             [&s](const std::string& line) { s.say(line); });
    // Called on the loop, inside mosquitto_loop_read.
    mosquitto_connect_with_flags_callback_set(s.client, [](mosquitto*, void* state, int code, int flags) {
        static_cast<State*>(state)->on_connect(code, flags);
    });
    mosquitto_publish_callback_set(s.client, [](mosquitto*, void* state, int mid) {
        static_cast<State*>(state)->unacknowledged.erase(mid);  // on the loop, in its turn
    });
    mosquitto_subscribe_callback_set(s.client, [](mosquitto*, void* state, int mid, int, const int*) {
        static_cast<State*>(state)->on_subscribed(mid);  // on the loop, in its turn
    });
    mosquitto_message_callback_set(s.client, [](mosquitto*, void* state, const mosquitto_message* message) {
        if (message) static_cast<State*>(state)->on_message(*message);
    });
    const std::string status = s.config.prefix + "/status";
    constexpr std::string_view offline = "offline";
    (void)mosquitto_will_set(s.client, status.c_str(), static_cast<int>(offline.size()), offline.data(), qos_at_least_once,
                             true);
    s.commands = std::make_unique<MqttCommands>(
        s.config, writer,
        [&s](std::string topic, std::string payload) {
            s.queue({std::move(topic), std::move(payload), false, qos_at_least_once});
        },
        [&s](const std::string& line) { s.say(line); });
    s.driver = std::make_unique<mqtt::LoopDriver>(loop, "lw-mqtt", s.client, s.config.host, s.timing.reconnect_first, s.timing.reconnect_last,
                                                  s.network_hooks());
    s.driver->start();
    if (s.config.discovery == MqttConfig::Discovery::homeassistant) {
        // The gateway's own device, which every controller's names as its via_device.
        const DiscoveryDocument gateway = gateway_document(s.config);
        s.queue({gateway.topic, json_text(gateway.config), true, qos_at_least_once});
    }
    s.subscription = cache.subscribe([&s](const ValueChange& change) { s.on_change(change); });
}

MqttBridge::~MqttBridge() {
    State& s = *state_;
    s.subscription.reset();
    // The writes under way finish first, and the network still publishes their results.
    s.commands->close();
    s.driver->stop();  // from here on the client is this thread's alone
    if (s.is_connected.load()) s.say_goodbye();
    s.commands.reset();
    mosquitto_destroy(s.client);
}

bool MqttBridge::connected() const { return state_->is_connected.load(); }

void MqttBridge::hand_over(const std::optional<MqttConfig>& next, const std::set<std::string>& next_devices) {
    State& s = *state_;
    const bool same_topics = next && next->broker == s.config.broker && next->prefix == s.config.prefix;
    std::lock_guard lock(s.mutex);
    s.gateway_continues = same_topics;
    s.continuing_devices = same_topics ? next_devices : std::set<std::string>{};
}

}  // namespace loopwire::gateway
