#include "gateway/sparkplug/sparkplug_node.hpp"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <deque>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <set>

#include <fmt/format.h>
#include <mosquitto.h>
#include <mqtt_protocol.h>
#include <nlohmann/json.hpp>

#include "client/device_status.hpp"
#include "common/atomic_file.hpp"
#include "common/peer_text.hpp"
#include "gateway/mqtt_client.hpp"
#include "gateway/mqtt_loop_driver.hpp"
#include "gateway/sparkplug/sparkplug_payloads.hpp"

namespace loopwire::gateway {
namespace {

// Sparkplug tells no publisher's identity: a DCMD came through the broker.
const WriteOrigin from_broker{"sparkplug", "broker", {}};

using namespace sparkplug;

constexpr int keepalive_seconds = 30;
constexpr int qos_at_least_once = 1;
constexpr int goodbye_turn_ms = 50;
// How long a node leaving for a primary host gone offline waits for its NDEATH's acknowledgement.
constexpr auto leave_limit = std::chrono::seconds(2);
// Writes from DCMDs waiting for their lines at once; more are refused as busy.
constexpr std::size_t max_pending_writes = 64;
constexpr std::string_view namespace_level = "spBv1.0";
const std::string rebirth_metric = "Node Control/Rebirth";
const std::string last_error_metric = "Device Control/Last Error";

std::uint64_t now_ms() {
    return static_cast<std::uint64_t>(
        std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count());
}

// A device's polls find it answering: it has a birth. "stale" still has one (its values are
// sent null), "no-reply" and "line-down" are its death, as is no status yet (the cache told
// nothing about the device).
bool alive(std::optional<device::DeviceStatus> status) {
    return status && (device::answered(*status) || *status == device::DeviceStatus::stale);
}

// What the polls said last about a device: its status and each parameter's latest change, read
// whole from the cache (ValueCache::told), never pieced together from callbacks that may be in
// the middle of one sample's changes (a device coming back would be born with the outage's
// nulls).
struct DevicePicture {
    std::optional<device::DeviceStatus> status;
    std::map<std::string, ValueChange> latest;  // by parameter name
};

// A device as the network knows it.
struct NodeDevice {
    std::string name;
    std::vector<MetricDefinition> metrics;  // [0]: Device Control/Last Error
    std::size_t parameter_count = 0;
    bool born = false;
    std::vector<std::optional<MetricSample>> sent;  // what the host application was told last
    std::vector<MetricProperties> born_with;        // each metric's properties in the last birth
    std::string last_error;
    bool last_error_due = false;  // a write's refusal waits to be told
};

// A write's outcome, from its completion to the network.
struct WriteOutcome {
    std::size_t device = 0;
    std::string error;  // empty: written
};

struct Command {
    std::string topic;
    std::string payload;
    bool retained = false;  // as its publisher sent it (MQTT 5 "retain as published")
};

// One DDATA the node would have sent while it was not born (store and forward): the device's
// changed metrics (by their index in NodeDevice::metrics) with the samples, and their time.
struct StoredData {
    std::string device;
    std::vector<std::pair<std::size_t, MetricSample>> metrics;
    std::uint64_t made_at = 0;  // ms since the epoch
    bool from_last_run = false;  // read from the history file: waits for its device's birth
};

// Whether two definitions of a device's metrics are the same to a host application: the same
// names, aliases, datatypes and bits, in the same order (the parameters behind them may be
// another configuration's).
bool same_definitions(const std::vector<MetricDefinition>& a, const std::vector<MetricDefinition>& b) {
    return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](const MetricDefinition& x, const MetricDefinition& y) {
        return x.name == y.name && x.alias == y.alias && x.type == y.type && x.bit == y.bit;
    });
}

}  // namespace

struct SparkplugNode::State {
    SparkplugConfig config;
    SparkplugTiming timing;
    GatewayLog log;
    const DeviceWriter* writer = nullptr;
    SparkplugLines lines;

    mosquitto* client = nullptr;
    std::atomic<bool> is_connected{false};

    const ValueCache* cache = nullptr;
    std::mutex mutex;  // guards the dirty flags, the outcomes and the pending count
    std::vector<char> dirty;  // by device: the polls told of a change since the network looked
    std::map<std::string, std::size_t> index;  // device name to its position
    std::vector<WriteOutcome> outcomes;
    std::size_t pending_writes = 0;
    std::condition_variable writes_done;  // notified when pending_writes drops to 0

    // The network's own (the loop's; after the driver stopped, the destructor's).
    std::vector<MetricDefinition> node_metrics;  // bdSeq, Node Control/Rebirth, Lines/...
    std::vector<std::optional<MetricSample>> node_sent;
    std::vector<NodeDevice> devices;
    std::uint64_t next_bd_seq = 0;
    std::uint64_t bd_seq = 0;  // of the connection now
    std::optional<std::uint64_t> kept_bd_seq;  // what state_file holds
    std::uint64_t seq = 0;     // of the next message
    bool node_born = false;
    bool host_online = false;
    // The timestamp of the newest host STATE taken: an older one, delivered late or out of
    // order, says nothing of the host now (Sparkplug 3.0, host application STATE).
    std::optional<std::uint64_t> host_state_timestamp;
    bool just_connected = false;
    // Leaving for it: the NDEATH published, its acknowledgement awaited until then, before the
    // DISCONNECT (leave_async).
    std::optional<std::chrono::steady_clock::time_point> leaving_until;
    std::vector<Command> inbox;  // taken in libmosquitto's callback, acted on after it
    std::chrono::steady_clock::time_point next_node_data{};
    bool told_unreachable = false;
    bool told_no_handshake = false;  // until a connection is accepted
    bool told_refused = false;
    int unacknowledged_goodbye = -1;

    // Aliases, given once per process: a metric (its device, "" for the node's own, and its
    // name) keeps its alias across rebirths and reloads, and no other metric ever takes it.
    std::map<std::pair<std::string, std::string>, std::uint64_t> aliases;
    std::uint64_t next_alias = 0;
    // After a reload (take_over): the devices gone, told dead at the next turn, and whether the
    // lines' metrics changed, which is a new NBIRTH.
    std::vector<std::string> deaths_due;
    bool node_birth_due = false;

    // Store and forward ([sparkplug] store_and_forward). The queue holds exactly the DDATA the
    // node would have sent, bounded by age and by count; the loop only appends and drops, never
    // waits. With [history] each DDATA is also queued for the history file's writer (`pending`,
    // sparkplug_pending.hpp says why a table of its own), so that a restart keeps it.
    std::deque<StoredData> stored;
    SparkplugPending pending;
    std::size_t stored_metrics = 0;
    std::atomic<std::size_t> stored_now{0};  // stored_metrics, for other threads (stored())
    std::uint64_t dropped_old = 0;    // this outage's values older than store_and_forward
    std::uint64_t dropped_count = 0;  // this outage's values dropped at max_stored
    bool told_store_full = false;
    bool born_once = false;  // the devices' `sent` is what a host was told: data is stored against it

    std::unique_ptr<mqtt::LoopDriver> driver;  // the network, on the loop
    ValueSubscription subscription;

    void say(const std::string& message) const {
        if (log) log("sparkplug " + config.broker + ": " + message);
    }

    // At the warning level (GatewayLog): what a person must see.
    void warn(const std::string& message) const {
        if (log) log(std::string(gateway_warning_prefix) + "sparkplug " + config.broker + ": " + message);
    }

    std::string node_topic(std::string_view type) const {
        return fmt::format("{}/{}/{}/{}", namespace_level, config.group_id, type, config.edge_node_id);
    }
    std::string device_topic(std::string_view type, const std::string& device) const {
        return fmt::format("{}/{}/{}/{}/{}", namespace_level, config.group_id, type, config.edge_node_id, device);
    }
    std::string host_topic() const { return fmt::format("{}/STATE/{}", namespace_level, config.primary_host); }

    std::uint64_t take_seq() {
        const std::uint64_t taken = seq;
        seq = (seq + 1) % 256;
        return taken;
    }

    void publish(const std::string& topic, const std::string& payload, int qos = 0, int* mid = nullptr) {
        // Sparkplug messages are never retained (but the host's STATE, which is not ours).
        (void)mosquitto_publish(client, mid, topic.c_str(), static_cast<int>(payload.size()), payload.data(), qos, false);
    }

    // --- the poll threads ---------------------------------------------------------------------

    void on_change(const ValueChange& change) {
        std::lock_guard lock(mutex);
        const auto found = index.find(change.device);
        if (found == index.end()) return;
        if (!std::exchange(dirty[found->second], 1)) driver->wake();
    }

    DevicePicture picture_of(const std::string& device) const {
        DevicePicture picture;
        for (auto& change : cache->told(device)) {
            if (change.about_device()) {
                picture.status = change.device_status;
            } else {
                picture.latest.insert_or_assign(change.parameter, std::move(change));
            }
        }
        return picture;
    }

    // --- births, data and deaths (the network) --------------------------------------------------

    std::string node_death() const {
        PayloadWriter death(now_ms(), std::nullopt);
        death.birth_metric(node_metrics[0], {static_cast<std::uint64_t>(bd_seq), quality_good, now_ms()}, nullptr);
        return death.bytes();
    }

    std::vector<MetricSample> node_samples() const {
        const std::uint64_t now = now_ms();
        std::vector<MetricSample> samples{{bd_seq, quality_good, now}, {false, quality_good, now}};
        const auto figures = lines ? lines() : std::vector<SparkplugLineFigures>{};
        for (const auto& line : figures) {
            samples.push_back({line.requests, quality_good, now});
            samples.push_back({line.answered, quality_good, now});
            samples.push_back({line.timeouts, quality_good, now});
            samples.push_back({line.open, quality_good, now});
        }
        samples.resize(node_metrics.size(), MetricSample{{}, quality_bad, now});
        return samples;
    }

    void birth_node() {
        seq = 0;
        PayloadWriter birth(now_ms(), take_seq());
        const auto samples = node_samples();
        for (std::size_t i = 0; i < node_metrics.size(); ++i) birth.birth_metric(node_metrics[i], samples[i], nullptr);
        node_sent.assign(samples.begin(), samples.end());
        publish(node_topic("NBIRTH"), birth.bytes());
        node_born = true;
        next_node_data = std::chrono::steady_clock::now() + timing.node_data_every;
        born_once = true;
        deaths_due.clear();  // the births say everything there is
        node_birth_due = false;
        for (auto& device : devices) device.born = false;
        publish_devices(true);
        forward_stored();
    }

    // The lines' figures that changed, when due.
    void node_data_when_due() {
        if (!node_born || std::chrono::steady_clock::now() < next_node_data) return;
        next_node_data = std::chrono::steady_clock::now() + timing.node_data_every;
        const auto samples = node_samples();
        std::vector<std::size_t> changed;
        for (std::size_t i = 2; i < samples.size(); ++i) {
            if (!node_sent[i] || !node_sent[i]->same_report(samples[i])) changed.push_back(i);
        }
        if (changed.empty()) return;
        PayloadWriter data(now_ms(), take_seq());
        for (const std::size_t i : changed) {
            data.data_metric(node_metrics[i], samples[i], false);
            node_sent[i] = samples[i];
        }
        publish(node_topic("NDATA"), data.bytes());
    }

    // Each metric's sample and properties from what the polls said; none until every polled
    // parameter was told.
    struct DeviceMetrics {
        std::vector<MetricSample> samples;
        std::vector<MetricProperties> properties;
    };
    std::optional<DeviceMetrics> metrics_of(const NodeDevice& device, const DevicePicture& seen) const {
        if (seen.latest.size() < device.parameter_count) return std::nullopt;
        DeviceMetrics picture;
        picture.samples.push_back({device.last_error, quality_good, now_ms()});
        picture.properties.emplace_back();
        for (std::size_t i = 1; i < device.metrics.size(); ++i) {
            const MetricDefinition& metric = device.metrics[i];
            const auto found = seen.latest.find(metric.parameter->name);
            if (found == seen.latest.end()) return std::nullopt;
            picture.samples.push_back(sample_of(metric, found->second));
            // A value that is missing says nothing of its unit and decimals: they stay what the
            // birth said (else every stale spell would be a rebirth).
            const bool known = !std::holds_alternative<std::monostate>(picture.samples.back().value);
            picture.properties.push_back(known || !device.born ? properties_of(metric, &found->second, config.writes)
                                                               : device.born_with[i]);
        }
        return picture;
    }

    void birth_device(NodeDevice& device, const DeviceMetrics& picture) {
        PayloadWriter birth(now_ms(), take_seq());
        for (std::size_t i = 0; i < device.metrics.size(); ++i) {
            birth.birth_metric(device.metrics[i], picture.samples[i], &picture.properties[i]);
        }
        publish(device_topic("DBIRTH", device.name), birth.bytes());
        device.born = true;
        device.sent.assign(picture.samples.begin(), picture.samples.end());
        device.born_with = picture.properties;
        device.last_error_due = false;
    }

    void death_device(NodeDevice& device) {
        PayloadWriter death(now_ms(), take_seq());
        publish(device_topic("DDEATH", device.name), death.bytes());
        device.born = false;
    }

    void data_device(NodeDevice& device, DeviceMetrics& picture) {
        if (device.last_error_due) {
            // Each refusal is told, even one worded as the last.
            picture.samples[0] = {device.last_error, quality_good, now_ms()};
            device.sent[0].reset();
            device.last_error_due = false;
        }
        std::vector<std::size_t> changed;
        for (std::size_t i = 0; i < device.metrics.size(); ++i) {
            if (!device.sent[i] || !device.sent[i]->same_report(picture.samples[i])) changed.push_back(i);
        }
        if (changed.empty()) return;
        PayloadWriter data(now_ms(), take_seq());
        for (const std::size_t i : changed) {
            const bool quality_news = picture.samples[i].quality != quality_good ||
                                      (device.sent[i] && device.sent[i]->quality != quality_good);
            data.data_metric(device.metrics[i], picture.samples[i], quality_news);
            device.sent[i] = picture.samples[i];
        }
        publish(device_topic("DDATA", device.name), data.bytes());
    }

    // Births, deaths and data for every device the polls told of since the last look (all of
    // them when `everything`, after the node's birth).
    void publish_devices(bool everything) {
        if (!node_born) return store_devices();
        std::vector<std::size_t> looked_at;
        {
            std::lock_guard lock(mutex);
            for (std::size_t i = 0; i < devices.size(); ++i) {
                if (!everything && !dirty[i] && !devices[i].last_error_due) continue;
                dirty[i] = 0;
                looked_at.push_back(i);
            }
        }
        for (const std::size_t i : looked_at) {
            NodeDevice& device = devices[i];
            const DevicePicture seen = picture_of(device.name);
            // The polls have told nothing of it yet: after a reload (a new cache), what the host
            // was told of it stands until they do.
            if (!seen.status) continue;
            if (!alive(seen.status)) {
                if (device.born) death_device(device);
                continue;
            }
            auto picture = metrics_of(device, seen);
            if (!picture) continue;
            // A unit or decimals the device's configuration changed (°C to °F) is a property of
            // the birth: the device is born again with it.
            if (!device.born || picture->properties != device.born_with) {
                birth_device(device, *picture);
            } else {
                data_device(device, *picture);
            }
        }
        // The last run's values wait for their device's birth (its polls may answer after the
        // NBIRTH): forwarded once it is born, before its next data.
        if (!everything && std::any_of(stored.begin(), stored.end(), [this](const StoredData& data) {
                const auto found = index.find(data.device);
                return found != index.end() && devices[found->second].born;
            })) {
            forward_stored();
        }
    }

    // --- store and forward ------------------------------------------------------------------------

    // While the node is not born (the broker away, the primary host offline): the DDATA each
    // device the host knows would have had, kept instead of sent. A device that dies meanwhile
    // keeps what was stored before; what it does after is in its next birth.
    void store_devices() {
        if (!config.store_and_forward || !born_once) return;
        std::vector<std::size_t> looked_at;
        {
            std::lock_guard lock(mutex);
            for (std::size_t i = 0; i < devices.size(); ++i) {
                if (dirty[i]) looked_at.push_back(i);
                dirty[i] = 0;
            }
        }
        for (const std::size_t i : looked_at) {
            NodeDevice& device = devices[i];
            if (!device.born) continue;
            const DevicePicture seen = picture_of(device.name);
            if (!seen.status) continue;
            if (!alive(seen.status)) {
                device.born = false;
                continue;
            }
            auto picture = metrics_of(device, seen);
            if (!picture || picture->properties != device.born_with) continue;  // a rebirth's, not data
            StoredData data{device.name, {}, now_ms()};
            for (std::size_t m = 1; m < device.metrics.size(); ++m) {
                if (device.sent[m] && device.sent[m]->same_report(picture->samples[m])) continue;
                data.metrics.emplace_back(m, picture->samples[m]);
                device.sent[m] = picture->samples[m];
            }
            if (data.metrics.empty()) continue;
            if (pending.add) pending.add(pending_of(data));
            keep(std::move(data));
        }
    }

    // What the history file keeps of a stored DDATA: its metrics by name.
    std::vector<PendingMetric> pending_of(const StoredData& data) const {
        std::vector<PendingMetric> rows;
        const auto found = index.find(data.device);
        if (found == index.end()) return rows;
        const NodeDevice& device = devices[found->second];
        for (const auto& [m, sample] : data.metrics)
            rows.push_back({data.made_at, data.device, device.metrics[m].name, sample});
        return rows;
    }

    // What the last run kept in the history file and did not forward: stored again, each DDATA as
    // it was made (its rows share the time and the device; one metric twice is two DDATA, made
    // in the same millisecond), metrics by name (one this
    // configuration does not have is left out: no host would know it).
    void take_pending(const std::vector<PendingMetric>& loaded) {
        std::size_t kept = 0;
        for (const PendingMetric& row : loaded) {
            const auto found = index.find(row.device);
            if (found == index.end()) continue;
            const auto& metrics = devices[found->second].metrics;
            const auto metric =
                std::find_if(metrics.begin(), metrics.end(),
                             [&row](const MetricDefinition& definition) { return definition.name == row.metric; });
            if (metric == metrics.end()) continue;
            const std::size_t m = static_cast<std::size_t>(metric - metrics.begin());
            const auto in_it = [m](const StoredData& data) {
                return std::any_of(data.metrics.begin(), data.metrics.end(),
                                   [m](const auto& kept_metric) { return kept_metric.first == m; });
            };
            if (stored.empty() || stored.back().made_at != row.made_at || stored.back().device != row.device ||
                in_it(stored.back())) {
                stored.push_back({row.device, {}, row.made_at, true});
            }
            stored.back().metrics.emplace_back(m, row.sample);
            ++stored_metrics;
            ++kept;
        }
        stored_now.store(stored_metrics);
        trim_to_most();
        if (kept > 0)
            say(fmt::format("store and forward: {} values the last run kept, to forward after the births", kept));
    }

    void keep(StoredData data) {
        stored_metrics += data.metrics.size();
        stored.push_back(std::move(data));
        drop_old();
        trim_to_most();
    }

    // At most max_stored values (the oldest dropped, counted); the history file follows.
    void trim_to_most() {
        const std::size_t before = stored.size();
        while (stored_metrics > timing.max_stored && stored.size() > 1) {
            dropped_count += stored.front().metrics.size();
            stored_metrics -= stored.front().metrics.size();
            stored.pop_front();
            if (!std::exchange(told_store_full, true)) {
                warn(fmt::format("store and forward holds {} values, its most: the oldest are dropped (counted when they "
                                 "are forwarded)", timing.max_stored));
            }
        }
        stored_now.store(stored_metrics);
        if (stored.size() < before) forget_before_front();
    }

    // The history file lets go of what memory dropped: rows made before the oldest kept.
    void forget_before_front() {
        if (pending.forget_before && !stored.empty()) pending.forget_before(stored.front().made_at);
    }

    void drop_old() {
        const std::uint64_t kept_for = static_cast<std::uint64_t>(config.store_and_forward->count());
        const std::uint64_t now = now_ms();
        const std::size_t before = stored.size();
        while (!stored.empty() && stored.front().made_at + kept_for < now) {
            dropped_old += stored.front().metrics.size();
            stored_metrics -= stored.front().metrics.size();
            stored.pop_front();
        }
        stored_now.store(stored_metrics);
        if (stored.size() < before) forget_before_front();
    }

    // After the births: what was stored, in the order it was made, each metric with
    // is_historical and its own timestamp. A value the births already carry (the same sample:
    // its time and value) is not sent again, nor is one of a device that is not born now (a
    // host would not know its aliases).
    void forward_stored() {
        if (!config.store_and_forward) return;
        drop_old();
        std::uint64_t forwarded = 0;
        std::uint64_t messages = 0;
        std::uint64_t in_births = 0;
        std::uint64_t unborn = 0;
        std::deque<StoredData> waiting;  // the last run's, of devices not born yet
        for (StoredData& data : stored) {
            const auto found = index.find(data.device);
            if (found != index.end() && !devices[found->second].born && data.from_last_run) {
                waiting.push_back(std::move(data));
                continue;
            }
            if (found == index.end() || !devices[found->second].born) {
                unborn += data.metrics.size();
                continue;
            }
            const NodeDevice& device = devices[found->second];
            std::vector<const std::pair<std::size_t, MetricSample>*> due;
            for (const auto& metric : data.metrics) {
                const auto& born = device.sent[metric.first];
                if (born && metric.second.timestamp == born->timestamp && metric.second.same_report(*born)) {
                    ++in_births;
                } else {
                    due.push_back(&metric);
                }
            }
            if (due.empty()) continue;
            PayloadWriter ddata(now_ms(), take_seq());
            for (const auto* metric : due) ddata.data_metric(device.metrics[metric->first], metric->second, true, true);
            publish(device_topic("DDATA", device.name), ddata.bytes());
            forwarded += due.size();
            ++messages;
        }
        if (forwarded + in_births + unborn + dropped_old + dropped_count > 0) {
            say(fmt::format("store and forward: {} values of the outage forwarded as historical in {} DDATA ({} already in the "
                            "births, {} of devices not born now, {} older than {} s and {} over the most of {} dropped)",
                            forwarded, messages, in_births, unborn, dropped_old, config.store_and_forward->count() / 1000,
                            dropped_count, timing.max_stored));
        }
        if (dropped_old + dropped_count > 0) {
            warn(fmt::format("store and forward dropped {} values of the outage ({} too old, {} over its most)",
                            dropped_old + dropped_count, dropped_old, dropped_count));
        }
        stored = std::move(waiting);
        stored_metrics = 0;
        for (const auto& data : stored) stored_metrics += data.metrics.size();
        stored_now.store(stored_metrics);
        dropped_old = dropped_count = 0;
        told_store_full = false;
        // The history file keeps what is still to forward, and nothing else: a run stopped from
        // here on forwards no value twice.
        if (pending.clear) {
            pending.clear();
            for (const auto& data : stored) pending.add(pending_of(data));
        }
    }

    // --- the devices of a configuration ----------------------------------------------------------

    std::uint64_t alias_for(const std::string& owner, const std::string& name) {
        const auto [found, added] = aliases.try_emplace({owner, name}, next_alias);
        if (added) ++next_alias;
        return found->second;
    }

    std::vector<MetricDefinition> node_metrics_for(const std::vector<SparkplugLineFigures>& figures) {
        std::vector<MetricDefinition> metrics;
        metrics.push_back({"bdSeq", alias_for("", "bdSeq"), DataType::uint64, nullptr, {}});
        metrics.push_back({rebirth_metric, alias_for("", rebirth_metric), DataType::boolean, nullptr, {}});
        for (const auto& line : figures) {
            const std::string base = "Lines/" + line.name + "/";
            metrics.push_back({base + "Requests", alias_for("", base + "Requests"), DataType::uint64, nullptr, {}});
            metrics.push_back({base + "Answered", alias_for("", base + "Answered"), DataType::uint64, nullptr, {}});
            metrics.push_back({base + "Timeouts", alias_for("", base + "Timeouts"), DataType::uint64, nullptr, {}});
            metrics.push_back({base + "Open", alias_for("", base + "Open"), DataType::boolean, nullptr, {}});
        }
        return metrics;
    }

    NodeDevice device_for(const SparkplugDevice& configured) {
        NodeDevice device;
        device.name = configured.name;
        device.metrics.push_back({last_error_metric, alias_for(configured.name, last_error_metric), DataType::string, nullptr, {}});
        for (const device::Parameter* parameter : configured.parameters) {
            std::uint64_t scratch = 0;
            for (auto& metric : parameter_metrics(*parameter, scratch)) {
                metric.alias = alias_for(configured.name, metric.name);
                device.metrics.push_back(std::move(metric));
            }
        }
        device.parameter_count = configured.parameters.size();
        return device;
    }

    // The devices `configured` names. One that carries on with the same metrics keeps what the
    // host was told of it and says nothing new; one added, or whose metrics changed, is born at
    // the next look; one gone dies at the next turn (if the host knows it).
    void adopt(const std::vector<SparkplugDevice>& configured) {
        for (const auto& device : devices) {
            const bool kept = std::any_of(configured.begin(), configured.end(),
                                          [&device](const SparkplugDevice& wanted) { return wanted.name == device.name; });
            if (!kept && device.born) deaths_due.push_back(device.name);
        }
        std::vector<NodeDevice> next;
        std::map<std::string, std::size_t> next_index;
        std::set<std::string> carried_on;
        for (const auto& wanted : configured) {
            NodeDevice device = device_for(wanted);
            const auto old = index.find(wanted.name);
            if (old != index.end() && same_definitions(devices[old->second].metrics, device.metrics)) {
                NodeDevice& kept = devices[old->second];
                kept.metrics = std::move(device.metrics);  // the same, with this configuration's parameters
                device = std::move(kept);
                carried_on.insert(wanted.name);
            } else if (old != index.end()) {
                say(fmt::format("device {}: its metrics changed: born again", wanted.name));
                device.last_error = devices[old->second].last_error;
            }
            next_index[wanted.name] = next.size();
            next.push_back(std::move(device));
        }
        std::lock_guard lock(mutex);
        devices = std::move(next);
        index = std::move(next_index);
        dirty.assign(devices.size(), 1);  // every device looked at once the polls tell of it
        // What was stored of a device gone or changed names aliases no host will know.
        std::erase_if(stored, [&carried_on](const StoredData& data) { return !carried_on.contains(data.device); });
        stored_metrics = 0;
        for (const auto& data : stored) stored_metrics += data.metrics.size();
        stored_now.store(stored_metrics);
    }

    // After a reload, on the loop: the deaths of the devices gone and, when the lines' metrics
    // changed, the node's birth again (seq 0, the same bdSeq, every device born after it).
    void after_reload() {
        const auto deaths = std::exchange(deaths_due, {});
        const bool birth = std::exchange(node_birth_due, false);
        if (!node_born) return;
        if (birth) {
            say("the lines changed with the reload: births again");
            return birth_node();
        }
        for (const auto& name : deaths) {
            say(fmt::format("device {} is no longer configured: DDEATH", name));
            PayloadWriter death(now_ms(), take_seq());
            publish(device_topic("DDEATH", name), death.bytes());
        }
    }

    // --- commands ------------------------------------------------------------------------------

    void on_node_command(const std::vector<CommandMetric>& metrics) {
        for (const auto& metric : metrics) {
            const bool rebirth = metric.name == rebirth_metric || (metric.alias && *metric.alias == node_metrics[1].alias);
            if (rebirth && metric.value == MetricValue{true}) {
                say("rebirth asked for (NCMD Node Control/Rebirth): births again");
                if (node_born) birth_node();
                continue;
            }
            say(fmt::format("NCMD metric {} = {} ignored: the node takes Node Control/Rebirth = true only",
                            metric.name.empty() && metric.alias ? fmt::format("alias {}", *metric.alias) : quoted_excerpt(metric.name),
                            value_words(metric.value)));
        }
    }

    const MetricDefinition* metric_of(const NodeDevice& device, const CommandMetric& metric) const {
        for (const auto& definition : device.metrics) {
            if ((metric.alias && definition.alias == *metric.alias) || (!metric.name.empty() && definition.name == metric.name)) {
                return &definition;
            }
        }
        return nullptr;
    }

    void refuse_write(std::size_t device, std::string why) {
        say(fmt::format("DCMD to {} refused: {}", devices[device].name, why));
        devices[device].last_error = std::move(why);
        devices[device].last_error_due = true;
    }

    // The assignments a DCMD asks for, or why it is refused (nothing is written then).
    Result<std::vector<WriteAssignment>> assignments_of(const NodeDevice& device, const std::vector<CommandMetric>& metrics) const {
        std::vector<WriteAssignment> assignments;
        for (const auto& metric : metrics) {
            const MetricDefinition* definition = metric_of(device, metric);
            if (!definition) {
                return make_error(ErrorKind::usage, fmt::format("{} is not a metric of {} (see its DBIRTH)",
                                                                metric.name.empty() && metric.alias ? fmt::format("alias {}", *metric.alias)
                                                                                                     : quoted_excerpt(metric.name),
                                                                device.name));
            }
            auto text = write_text(*definition, metric.value);
            if (!text) return text.error();
            assignments.push_back({definition->parameter->name, std::move(*text)});
        }
        if (assignments.empty()) return make_error(ErrorKind::usage, "the DCMD holds no metric");
        return assignments;
    }

    void on_device_command(std::size_t index_of_device, const std::vector<CommandMetric>& metrics) {
        NodeDevice& device = devices[index_of_device];
        // Worked out first, for the audit of a refusal too: what the DCMD asked for.
        auto assignments = assignments_of(device, metrics);
        // A refusal here, before the writer has the write, is audited as the writer audits its own.
        const auto refuse = [&](std::string why) {
            std::vector<WriteAssignment> asked;
            if (assignments) {
                asked = *assignments;
            } else {
                for (const auto& metric : metrics) asked.push_back({metric.name, value_words(metric.value)});
            }
            writer->audit_refusal(device.name, asked, from_broker, why);
            refuse_write(index_of_device, std::move(why));
        };
        if (!config.writes) return refuse("writes are off (set writes = true in [sparkplug] to take DCMDs)");
        if (!node_born) return refuse("the node is dead (its NDEATH is out); nothing was sent");
        // The writer's policy, in the words every front gives (device_writer.hpp); a device
        // dead for another reason (no poll has told of it yet) is refused here.
        if (auto silent = writer->refusal(device.name)) return refuse(silent->message);
        if (!device.born) return refuse("the device does not answer now (DDEATH); nothing was sent");
        if (!assignments) return refuse(assignments.error().message);
        std::optional<std::size_t> waiting;
        {
            std::lock_guard lock(mutex);
            if (pending_writes >= max_pending_writes) {
                waiting = pending_writes;
            } else {
                ++pending_writes;
            }
        }
        // Refused outside the lock: the audit reads the value cache, whose changes this node
        // takes under it.
        if (waiting) return refuse(fmt::format("{} writes are waiting already; write again later", *waiting));
        const bool queued = writer->write_async(device.name, std::move(*assignments), [this, index_of_device](Result<WrittenValues> written) {
            std::lock_guard lock(mutex);
            outcomes.push_back({index_of_device, written ? std::string() : written.error().message});
            driver->wake();
            if (--pending_writes == 0) writes_done.notify_all();
        }, from_broker);
        if (!queued) {
            {
                std::lock_guard lock(mutex);
                --pending_writes;
            }
            refuse_write(index_of_device, "the device's line has too many writes waiting; write again later");
        }
    }

    void take_outcomes() {
        std::vector<WriteOutcome> taken;
        {
            std::lock_guard lock(mutex);
            taken.swap(outcomes);
        }
        for (auto& outcome : taken) {
            NodeDevice& device = devices[outcome.device];
            if (outcome.error.empty()) {
                if (device.last_error.empty()) continue;
                device.last_error.clear();  // the last write went through: nothing to report
                device.last_error_due = true;
            } else {
                refuse_write(outcome.device, outcome.error);
            }
        }
    }

    // Whether the host's STATE is older than one already taken (then it is ignored), and if not
    // its timestamp noted.
    bool outdated_state(const nlohmann::json& json) {
        if (!json.is_object() || !json.contains("timestamp") || !json["timestamp"].is_number_unsigned()) return false;
        const auto timestamp = json["timestamp"].get<std::uint64_t>();
        if (host_state_timestamp && timestamp < *host_state_timestamp) {
            say(fmt::format("primary host {} STATE of {} ignored: older than the one of {} already taken",
                            config.primary_host, timestamp, *host_state_timestamp));
            return true;
        }
        host_state_timestamp = timestamp;
        return false;
    }

    void on_host_state(std::string_view payload) {
        // Sparkplug 3.0 (host application STATE): {"online": true|false, "timestamp": ms}; the
        // plain "ONLINE"/"OFFLINE" of Sparkplug 2.2 hosts is taken too.
        bool online = payload == "ONLINE";
        const auto json = nlohmann::json::parse(payload, nullptr, false);
        if (outdated_state(json)) return;
        if (json.is_object() && json.contains("online") && json["online"].is_boolean()) online = json["online"].get<bool>();
        if (online == host_online) return;
        host_online = online;
        if (leaving_until) {
            // This session's NDEATH is out: its bdSeq may not be born again. The next session
            // (the next bdSeq) births once the host's retained STATE says it is online.
            return;
        }
        if (online) {
            say(fmt::format("primary host {} is online: births", config.primary_host));
            birth_node();
        } else if (node_born) {
            say(fmt::format("primary host {} went offline: NDEATH, disconnecting until it is back", config.primary_host));
            leave_async();
        }
    }

    // A command published with the retain flag is refused unread: the broker keeps it and hands
    // it to the node at every subscription, so that an old write would be made again at each
    // reconnection, after any written since. Commands are taken live only.
    void refuse_retained(const Command& command, const std::string& ncmd) {
        const std::string why = mqtt::retained_command_refusal(command.topic);
        if (command.topic == ncmd) return say(fmt::format("NCMD refused: {}", why));
        const std::string prefix = device_topic("DCMD", "");
        const auto found =
            command.topic.starts_with(prefix) ? index.find(command.topic.substr(prefix.size())) : index.end();
        if (found == index.end()) return say(fmt::format("{} refused: {}", quoted_excerpt(command.topic), why));
        refuse_write(found->second, why);
    }

    void take_commands() {
        std::vector<Command> taken;
        taken.swap(inbox);
        const std::string ncmd = node_topic("NCMD");
        for (auto& command : taken) {
            if (!config.primary_host.empty() && command.topic == host_topic()) {
                on_host_state(command.payload);
                continue;
            }
            if (command.retained) {
                refuse_retained(command, ncmd);
                continue;
            }
            if (command.payload.size() > config.max_payload) {
                say(fmt::format("{} of {} bytes refused unread (at most {})", quoted_excerpt(command.topic), command.payload.size(),
                                config.max_payload));
                continue;
            }
            auto metrics = decode_command(command.payload);
            if (!metrics) {
                say(fmt::format("{}: {}", quoted_excerpt(command.topic), metrics.error().message));
                continue;
            }
            if (command.topic == ncmd) {
                on_node_command(*metrics);
                continue;
            }
            const std::string prefix = device_topic("DCMD", "");
            const auto found = command.topic.starts_with(prefix) ? index.find(command.topic.substr(prefix.size())) : index.end();
            if (found == index.end()) {
                say(fmt::format("{}: no such device of this node; ignored", quoted_excerpt(command.topic)));
                continue;
            }
            on_device_command(found->second, *metrics);
        }
    }

    // --- the connection ------------------------------------------------------------------------

    void on_connect(int code) {
        if (code != 0) {
            if (!std::exchange(told_refused, true)) {
                say(fmt::format("the broker refused the connection: {}; retrying in the background",
                                mosquitto_reason_string(code)));
            }
            return;
        }
        just_connected = true;
    }

    void on_message(const mosquitto_message& message) {
        if (!message.topic) return;
        inbox.push_back({message.topic,
                         std::string(static_cast<const char*>(message.payload),
                                     static_cast<std::size_t>(std::max(message.payloadlen, 0))),
                         message.retain});
    }

    // After a connection was made: the commands' subscriptions, then the births (at once, or
    // once the primary host says it is online).
    void announce() {
        is_connected.store(true);
        told_unreachable = false;
        told_refused = false;
        told_no_handshake = false;
        say(fmt::format("connected as edge node {}/{} (bdSeq {})", config.group_id, config.edge_node_id, bd_seq));
        // The retain flag as the publisher set it (MQTT 5): a command published retained is
        // refused whether it comes live or as the copy the broker keeps (refuse_retained).
        (void)mosquitto_subscribe_v5(client, nullptr, node_topic("NCMD").c_str(), qos_at_least_once,
                                     MQTT_SUB_OPT_RETAIN_AS_PUBLISHED, nullptr);
        (void)mosquitto_subscribe_v5(client, nullptr, device_topic("DCMD", "+").c_str(), qos_at_least_once,
                                     MQTT_SUB_OPT_RETAIN_AS_PUBLISHED, nullptr);
        host_online = false;
        node_born = false;
        if (config.primary_host.empty()) {
            birth_node();
        } else {
            (void)mosquitto_subscribe(client, nullptr, host_topic().c_str(), qos_at_least_once);
            say(fmt::format("waiting for primary host {} to be online ({})", config.primary_host, host_topic()));
        }
    }

    // The will of the next connection: NDEATH with its bdSeq (Sparkplug 3.0: bdSeq counts the
    // node's MQTT CONNECTs; the session's NBIRTH and NDEATH carry the same). An attempt that never
    // reached the broker (unreachable: no TCP connection, so no CONNECT sent) leaves the count as
    // it was; one that did moves it on (lost), so that the next session's will never carries the
    // bdSeq of a death already published.
    int connect() {
        bd_seq = next_bd_seq;
        keep_next_bd_seq((bd_seq + 1) % 256);
        const std::string death = node_death();
        (void)mosquitto_will_set(client, node_topic("NDEATH").c_str(), static_cast<int>(death.size()), death.data(),
                                 qos_at_least_once, false);
        return mosquitto_connect_async(client, config.host.c_str(), config.port, keepalive_seconds);
    }

    // The bdSeq a restart starts from (state_file): the one after this connection's, written
    // before the CONNECT goes, so a node killed after it never births again with the bdSeq of
    // the death the broker published for it. Written once per new value, not per retry.
    void keep_next_bd_seq(std::uint64_t next) {
        if (config.state_file.empty() || kept_bd_seq == next) return;
        if (auto written = write_file_atomically(config.state_file.string(), fmt::format("bdSeq {}\n", next)); !written) {
            warn(fmt::format("cannot keep the next bdSeq in {} ({}); a restart counts from 0 again",
                            config.state_file.string(), written.error().message));
            return;
        }
        kept_bd_seq = next;
    }

    // The bdSeq the last run kept; 0 when there is none yet or it cannot be read (said).
    void take_kept_bd_seq() {
        if (config.state_file.empty()) return;
        std::ifstream in(config.state_file);
        if (!in) return;  // the first start: none kept yet
        std::string word;
        std::uint64_t kept = 0;
        if (in >> word >> kept && word == "bdSeq" && kept < 256) {
            next_bd_seq = kept;
            kept_bd_seq = kept;
            return;
        }
        warn(fmt::format("{} does not hold a bdSeq (\"bdSeq N\", N 0..255); counting from 0",
                        config.state_file.string()));
    }

    void lost(std::string_view why) {
        if (is_connected.exchange(false)) say(fmt::format("connection lost ({})", why));
        node_born = false;
        told_unreachable = false;
        next_bd_seq = (bd_seq + 1) % 256;
    }

    // --- the network, on the loop (gateway/mqtt_loop_driver.hpp) ----------------------------------

    mqtt::LoopDriver::Hooks network_hooks() {
        mqtt::LoopDriver::Hooks hooks;
        hooks.connect = [this] { return connect(); };
        hooks.unreachable = [this](const std::string& why) {
            if (!std::exchange(told_unreachable, true)) say(fmt::format("cannot reach the broker ({}); retrying in the background", why));
        };
        hooks.turned = [this] { return turned(); };
        hooks.lost = [this](const std::string& why) {
            if (std::exchange(leaving_until, std::nullopt)) return lost("the primary host is offline");
            if (!is_connected.load() && !std::exchange(told_no_handshake, true)) say(mqtt::handshake_failure(why));
            lost(why);
        };
        return hooks;
    }

    // After each turn of the network work: whether a connection was accepted in it.
    bool turned() {
        const bool accepted = std::exchange(just_connected, false);
        if (accepted) announce();
        after_reload();
        take_commands();
        take_outcomes();
        publish_devices(false);
        node_data_when_due();
        if (leaving_until && (unacknowledged_goodbye < 0 || std::chrono::steady_clock::now() >= *leaving_until)) {
            // Acknowledged (or given up on): the DISCONNECT; the connection's end comes next,
            // and the driver's reconnection after it.
            unacknowledged_goodbye = -1;
            (void)mosquitto_disconnect(client);
        }
        return accepted;
    }

    // On the loop, for a primary host gone offline: the NDEATH now, the DISCONNECT once it is
    // acknowledged (turned), without holding the loop meanwhile.
    void leave_async() {
        int mid = -1;
        publish(node_topic("NDEATH"), node_death(), qos_at_least_once, &mid);
        unacknowledged_goodbye = mid;
        leaving_until = std::chrono::steady_clock::now() + leave_limit;
        node_born = false;
    }

    // The node's own death (Sparkplug 3.0: NDEATH before a clean disconnect, which does not
    // fire the will): published at QoS 1 and acknowledged, then DISCONNECT written out, so that
    // a connection made next (a primary host's return) is not a takeover of this one, on which
    // the broker would also publish the will and libmosquitto send the NDEATH again.
    void leave() {
        if (!leaving_until) {  // else it is out already (leave_async): a second would say the same death twice
            int mid = -1;
            publish(node_topic("NDEATH"), node_death(), qos_at_least_once, &mid);
            unacknowledged_goodbye = mid;
        }
        const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(2);
        while (unacknowledged_goodbye >= 0 && std::chrono::steady_clock::now() < give_up &&
               mosquitto_loop(client, goodbye_turn_ms, 1) == MOSQ_ERR_SUCCESS) {
        }
        unacknowledged_goodbye = -1;
        (void)mosquitto_disconnect(client);
        // Until the socket is closed (the loop then says so), at most half a second.
        const auto closed_by = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
        while (std::chrono::steady_clock::now() < closed_by && mosquitto_loop(client, goodbye_turn_ms, 1) == MOSQ_ERR_SUCCESS) {
        }
        node_born = false;
    }

    void say_goodbye() {
        leave();
        is_connected.store(false);
    }

    void wait_for_writes() {
        std::unique_lock lock(mutex);
        writes_done.wait(lock, [this] { return pending_writes == 0; });
    }
};

SparkplugNode::SparkplugNode(SparkplugConfig config, std::vector<SparkplugDevice> devices, const DeviceWriter& writer,
                             ValueCache& cache, SparkplugLines lines, GatewayLog log, SparkplugTiming timing,
                             boost::asio::io_context* loop, SparkplugPending pending)
    : state_(std::make_unique<State>()) {
    mqtt::init_library_once();
    State& s = *state_;
    s.config = std::move(config);
    s.timing = timing;
    s.log = std::move(log);
    s.writer = &writer;
    s.lines = std::move(lines);
    s.take_kept_bd_seq();
    // Aliases from the configuration: the node's metrics, then each device's in order.
    s.node_metrics = s.node_metrics_for(s.lines ? s.lines() : std::vector<SparkplugLineFigures>{});
    s.adopt(devices);
    if (s.config.store_and_forward) s.take_pending(pending.loaded);
    pending.loaded.clear();
    s.pending = std::move(pending);
    s.cache = &cache;
    // A clean session (Sparkplug 3.0: edge nodes connect with Clean Session set): commands sent
    // while the node was away are not for it, its births make the host application's picture.
    s.client = mosquitto_new(s.config.client_id.c_str(), true, &s);
    if (!s.client) throw std::bad_alloc();
    // MQTT 5 (Sparkplug 3.0 takes 3.1.1 or 5), for the retain flag of a command as it was
    // published: under 3.1.1 a command published retained while the node is subscribed comes
    // without it (3.3.1.3) and could not be told from a live one. Clean Start with no session
    // expiry is 3.1.1's clean session.
    (void)mosquitto_int_option(s.client, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V5);
    mqtt::send_without_delay(s.client);
    mqtt::configure_security(s.client, s.config.tls, s.config.username, s.config.password,
                             [&s](const std::string& line) { s.say(line); });
    mosquitto_connect_callback_set(s.client, [](mosquitto*, void* state, int code) { static_cast<State*>(state)->on_connect(code); });
    mosquitto_publish_callback_set(s.client, [](mosquitto*, void* state, int mid) {
        auto& self = *static_cast<State*>(state);
        if (mid == self.unacknowledged_goodbye) self.unacknowledged_goodbye = -1;
    });
    mosquitto_message_callback_set(s.client, [](mosquitto*, void* state, const mosquitto_message* message) {
        if (message) static_cast<State*>(state)->on_message(*message);
    });
    s.driver = std::make_unique<mqtt::LoopDriver>(loop, "lw-sparkplug", s.client, s.config.host, s.timing.reconnect_first,
                                                  s.timing.reconnect_last, s.network_hooks());
    s.driver->start();
    s.subscription = cache.subscribe([&s](const ValueChange& change) { s.on_change(change); });
}

SparkplugNode::~SparkplugNode() {
    State& s = *state_;
    s.subscription.reset();
    if (s.driver) s.driver->stop();  // from here on the client is this thread's alone
    if (s.is_connected.load()) s.say_goodbye();
    // The writes still under way end on their lines (within the writer's time limit), and their
    // completions hold this state: it goes once the last has run.
    s.wait_for_writes();
    mosquitto_destroy(s.client);
}

bool SparkplugNode::release() {
    State& s = *state_;
    s.subscription.reset();
    s.driver->stop();
    s.wait_for_writes();
    // A connection half made (its CONNACK awaited) cannot be picked up where it is; a node
    // leaving for a primary host gone offline has said its death already.
    const bool half_made = !s.is_connected.load() && mosquitto_socket(s.client) >= 0;
    if (half_made || s.leaving_until) return false;
    s.driver.reset();  // while its loop is still there: its waits go with it
    s.cache = nullptr;
    s.writer = nullptr;
    s.lines = {};
    return true;
}

void SparkplugNode::take_over(std::vector<SparkplugDevice> devices, const DeviceWriter& writer, ValueCache& cache,
                              SparkplugLines lines, GatewayLog log, boost::asio::io_context* loop,
                              SparkplugPending pending) {
    State& s = *state_;
    pending.loaded.clear();
    s.pending = std::move(pending);
    s.writer = &writer;
    s.lines = std::move(lines);
    s.log = std::move(log);
    auto node_metrics = s.node_metrics_for(s.lines ? s.lines() : std::vector<SparkplugLineFigures>{});
    if (!same_definitions(node_metrics, s.node_metrics)) {
        s.node_metrics = std::move(node_metrics);
        s.node_birth_due = true;
    }
    s.adopt(devices);
    // Worded before the driver starts: from then on its thread may connect and move bdSeq on.
    const std::string carried_on =
        fmt::format("carries on across the reload with {} devices (bdSeq {}, no new session)", s.devices.size(), s.bd_seq);
    s.cache = &cache;
    s.driver = std::make_unique<mqtt::LoopDriver>(loop, "lw-sparkplug", s.client, s.config.host, s.timing.reconnect_first,
                                                  s.timing.reconnect_last, s.network_hooks());
    // The connection the last gateway's loop drove goes on (or, when there was none, the next
    // attempt starts now).
    if (s.is_connected.load()) {
        s.driver->resume();
    } else {
        s.driver->start();
    }
    s.subscription = cache.subscribe([&s](const ValueChange& change) { s.on_change(change); });
    s.driver->wake();  // the deaths and births the reload calls for
    s.say(carried_on);
}

bool SparkplugNode::connected() const { return state_->is_connected.load(); }

std::size_t SparkplugNode::stored() const { return state_->stored_now.load(); }

}  // namespace loopwire::gateway
