// A gateway front that publishes to a real broker, from the value cache to a subscriber: the
// MQTT front or the Sparkplug B edge node:
//   rate     value changes/s the front carries from the poller's cache to a subscriber, with
//            every parameter changing in every sample, as fast as they go through (the poller
//            keeps at most 16 samples ahead of the subscriber);
//   latency  poll -> subscriber at 10 samples/s of every parameter (p50, p99, max), and the
//            peer in the same run (MQTT front only): a plain libmosquitto publisher that sends
//            each sample as the same retained messages in a tight loop, the broker's floor for a
//            burst of that size (the broker reads and forwards one message at a time);
//   memory   resident memory the cache and the front take per 1,000 parameters, published.
// The parameters are synthetic (int16, one decimal, "°C"), 50 per device; the samples are what
// the poll groups hand the value cache. The subscriber reads the MQTT front's values as text
// and decodes the Sparkplug node's DDATA with protobuf. Prints one line per figure, each
// beginning with the front's name.
//
// usage: mqtt_throughput PORT PARAMETERS SECONDS [mqtt|sparkplug]
//        (a mosquitto broker listening on 127.0.0.1:PORT)
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <string_view>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <mosquitto.h>

#include "gateway/device_writer.hpp"
#include "gateway/engine.hpp"
#include "gateway/mqtt_bridge.hpp"
#include "gateway/sparkplug/sparkplug_node.hpp"
#include "gateway/value_cache.hpp"
#include "sparkplug/sparkplug_b.pb.h"

namespace {

using namespace loopwire;
using SteadyClock = std::chrono::steady_clock;
using namespace std::chrono_literals;
constexpr std::size_t per_device = 50;
const std::string prefix = "bench/gw";
const std::string sparkplug_data = "spBv1.0/bench/DDATA/gw/+";

long resident_kib() {
    std::ifstream status("/proc/self/status");
    std::string line;
    while (std::getline(status, line)) {
        if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
    }
    return 0;
}

// A subscriber to the values (PREFIX/+/+, or the node's DDATA) that notes when each sample
// number arrives.
class Subscriber {
public:
    Subscriber(int port, bool sparkplug) : sparkplug_(sparkplug) {
        client_ = mosquitto_new(nullptr, true, this);
        mosquitto_message_callback_set(client_, [](mosquitto*, void* self, const mosquitto_message* message) {
            static_cast<Subscriber*>(self)->arrived(*message);
        });
        if (mosquitto_connect(client_, "127.0.0.1", port, 30) != MOSQ_ERR_SUCCESS) throw std::runtime_error("no broker");
        const std::string filter = sparkplug ? sparkplug_data : prefix + "/+/+";
        mosquitto_subscribe(client_, nullptr, filter.c_str(), 0);
        mosquitto_loop_start(client_);
    }
    ~Subscriber() {
        mosquitto_disconnect(client_);
        mosquitto_loop_stop(client_, false);
        mosquitto_destroy(client_);
    }
    // Waits until `count` values of sample `sample` (or later) came, at most `limit`.
    bool wait(long sample, std::size_t count, std::chrono::milliseconds limit) {
        std::unique_lock lock(mutex_);
        awaited_ = {sample, count};
        const bool arrived = changed_.wait_for(lock, limit, [&] { return arrivals_[sample] >= count; });
        awaited_.reset();
        return arrived;
    }
    // Waits until a value of `sample` or a later one has arrived: how far the front has got.
    bool wait_reached(long sample, std::chrono::milliseconds limit) {
        std::unique_lock lock(mutex_);
        awaited_highest_ = sample;
        const bool reached = changed_.wait_for(lock, limit, [&] { return highest_ >= sample; });
        awaited_highest_.reset();
        return reached;
    }
    void expect(long sample, SteadyClock::time_point sent) {
        std::lock_guard lock(mutex_);
        sent_[sample] = sent;
    }
    std::vector<double> latencies_ms() {
        std::lock_guard lock(mutex_);
        return latencies_;
    }
    void clear() {
        std::lock_guard lock(mutex_);
        latencies_.clear();
    }
    // Values arrived so far, of every sample.
    std::size_t total() {
        std::lock_guard lock(mutex_);
        return total_;
    }
    SteadyClock::time_point last_arrival() {
        std::lock_guard lock(mutex_);
        return last_;
    }

private:
    // The values a message carries, each the sample number / 10.
    std::vector<double> values_of(const mosquitto_message& message) const {
        if (!sparkplug_) {
            // PREFIX/DEVICE/status and PREFIX/DEVICE/availability: the device's, not a value.
            const std::string_view topic(message.topic);
            if (topic.ends_with("/status") || topic.ends_with("/availability")) return {};
            const char* text = static_cast<const char*>(message.payload);
            double value = 0;
            // A status word in place of a value ("no-reply") is no sample: not counted as one.
            if (std::from_chars(text, text + message.payloadlen, value).ec != std::errc{}) return {};
            return {value};
        }
        loopwire::sparkplug::b::Payload payload;
        if (!payload.ParseFromArray(message.payload, message.payloadlen)) return {};
        std::vector<double> values;
        for (const auto& metric : payload.metrics()) {
            if (metric.value_case() == loopwire::sparkplug::b::Payload::Metric::kDoubleValue) values.push_back(metric.double_value());
        }
        return values;
    }

    void arrived(const mosquitto_message& message) {
        const auto now = SteadyClock::now();
        const auto values = values_of(message);
        std::lock_guard lock(mutex_);
        for (const double value : values) {
            const long sample = std::lround(value * 10);
            ++arrivals_[sample];
            ++total_;
            highest_ = std::max(highest_, sample);
            last_ = now;
            if (auto found = sent_.find(sample); found != sent_.end()) {
                latencies_.push_back(std::chrono::duration<double, std::milli>(now - found->second).count());
            }
        }
        // The instrument must cost less than what it measures (mosquitto_sub, the peer's
        // subscriber, is a plain C loop): the waiter is woken only when what it waits for came.
        if ((awaited_ && arrivals_[awaited_->first] >= awaited_->second) ||
            (awaited_highest_ && highest_ >= *awaited_highest_)) {
            changed_.notify_all();
        }
    }

    bool sparkplug_ = false;
    mosquitto* client_ = nullptr;
    std::mutex mutex_;
    std::condition_variable changed_;
    std::optional<std::pair<long, std::size_t>> awaited_;  // (sample, count) the waiter wants
    std::optional<long> awaited_highest_;                  // or the sample it waits to see reached
    long highest_ = 0;
    std::map<long, std::size_t> arrivals_;
    std::size_t total_ = 0;
    std::map<long, SteadyClock::time_point> sent_;
    std::vector<double> latencies_;
    SteadyClock::time_point last_{};
};

// Devices of synthetic parameters, sampled with every value set to the sample number.
class Plant {
public:
    explicit Plant(std::size_t parameters) {
        parameters_.reserve(parameters);
        for (std::size_t i = 0; i < parameters; ++i) {
            device::Parameter parameter;
            parameter.name = fmt::format("p{:04}", i);
            parameter.type = device::ValueType::int16;
            parameter.decimals = 1;
            parameter.unit = "°C";
            parameters_.push_back(parameter);
        }
        for (std::size_t first = 0; first < parameters; first += per_device) {
            std::vector<const device::Parameter*> mine;
            for (std::size_t i = first; i < std::min(parameters, first + per_device); ++i) mine.push_back(&parameters_[i]);
            devices_.push_back(device::watch(fmt::format("d{:03}", first / per_device), mine));
        }
    }
    // The devices as the Sparkplug node knows them: names and the parameters polled.
    std::vector<gateway::SparkplugDevice> sparkplug_devices() const {
        std::vector<gateway::SparkplugDevice> devices;
        for (std::size_t d = 0; d < devices_.size(); ++d) {
            gateway::SparkplugDevice& device = devices.emplace_back();
            device.name = fmt::format("d{:03}", d);
            for (const auto& value : devices_[d].values) device.parameters.push_back(value.parameter);
        }
        return devices;
    }
    void sample(gateway::ValueCache& cache, long number) {
        for (std::size_t d = 0; d < devices_.size(); ++d) {
            device::ReadReport report;
            for (const auto& value : devices_[d].values) {
                device::ParameterReading& reading = report.readings.emplace_back();
                reading.parameter = value.parameter;
                reading.value.emplace();
                reading.value->value = static_cast<double>(number) / 10.0;
                reading.value->raw = static_cast<std::uint16_t>(number);
            }
            device::record_poll(devices_[d], report, true, "", device::MonitorClock::now());
            cache.update(fmt::format("d{:03}", d), devices_[d], std::chrono::system_clock::now());
        }
    }

private:
    std::vector<device::Parameter> parameters_;
    std::vector<device::WatchedDevice> devices_;
};

// The front under test, connecting to the broker.
class Front {
public:
    Front(bool sparkplug, int port, gateway::ValueCache& cache, const gateway::DeviceWriter& writer, const Plant& plant) {
        const std::string broker = fmt::format("mqtt://127.0.0.1:{}", port);
        const std::string client_id = fmt::format("loopwire-bench-{}", ::getpid());
        if (sparkplug) {
            gateway::SparkplugConfig config;
            config.broker = broker;
            config.host = "127.0.0.1";
            config.port = static_cast<std::uint16_t>(port);
            config.group_id = "bench";
            config.edge_node_id = "gw";
            config.client_id = client_id;
            node_ = std::make_unique<gateway::SparkplugNode>(config, plant.sparkplug_devices(), writer, cache,
                                                             gateway::SparkplugLines{}, gateway::GatewayLog{});
            return;
        }
        gateway::MqttConfig config;
        config.broker = broker;
        config.host = "127.0.0.1";
        config.port = static_cast<std::uint16_t>(port);
        config.prefix = prefix;
        config.republish.reset();
        config.client_id = client_id;
        bridge_ = std::make_unique<gateway::MqttBridge>(config, writer, cache, gateway::GatewayLog{});
    }
    bool connected() const { return node_ ? node_->connected() : bridge_->connected(); }

private:
    std::unique_ptr<gateway::MqttBridge> bridge_;
    std::unique_ptr<gateway::SparkplugNode> node_;
};

// The peer of the latency figure: the front's messages (PREFIX/DEVICE/PARAMETER, the value as
// text, retained, QoS 0) from a client that does nothing else, written as it publishes.
class PlainPublisher {
public:
    PlainPublisher(int port, std::size_t parameters) {
        client_ = mosquitto_new(nullptr, true, nullptr);
        (void)mosquitto_int_option(client_, MOSQ_OPT_TCP_NODELAY, 1);
        if (mosquitto_connect(client_, "127.0.0.1", port, 30) != MOSQ_ERR_SUCCESS) throw std::runtime_error("no broker");
        for (std::size_t i = 0; i < parameters; ++i) topics_.push_back(fmt::format("{}/d{:03}/p{:04}", prefix, i / per_device, i));
    }
    ~PlainPublisher() {
        mosquitto_disconnect(client_);
        mosquitto_destroy(client_);
    }
    void sample(long number) {
        const std::string text = fmt::format("{:.1f}", static_cast<double>(number) / 10.0);
        for (const auto& topic : topics_) {
            mosquitto_publish(client_, nullptr, topic.c_str(), static_cast<int>(text.size()), text.data(), 0, true);
        }
        (void)mosquitto_loop(client_, 0, 1);  // the broker's acknowledgements and pings, not waited for
    }

private:
    mosquitto* client_ = nullptr;
    std::vector<std::string> topics_;
};

double percentile(std::vector<double> values, double share) {
    if (values.empty()) return 0;
    std::sort(values.begin(), values.end());
    return values[std::min(values.size() - 1, static_cast<std::size_t>(share * static_cast<double>(values.size())))];
}

// Sends a burst of every parameter's new value 10 times a second for `seconds` and returns each
// value's time from the burst's start to its arrival (empty, and said, if some never came).
template <typename Send>
std::vector<double> latencies_ms(Subscriber& subscriber, long& sample, std::size_t parameters, std::chrono::seconds seconds,
                                 Send send) {
    subscriber.clear();
    const auto end = SteadyClock::now() + seconds;
    while (SteadyClock::now() < end) {
        ++sample;
        subscriber.expect(sample, SteadyClock::now());
        send(sample);
        std::this_thread::sleep_for(100ms);
    }
    if (!subscriber.wait(sample, parameters, 30s)) {
        std::fprintf(stderr, "the latency samples did not all arrive\n");
        return {};
    }
    return subscriber.latencies_ms();
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 4 && argc != 5) {
        std::fprintf(stderr, "usage: %s PORT PARAMETERS SECONDS [mqtt|sparkplug]\n", argv[0]);
        return 2;
    }
    const int port = std::stoi(argv[1]);
    const auto parameters = static_cast<std::size_t>(std::stoul(argv[2]));
    const auto seconds = std::chrono::seconds(std::stoi(argv[3]));
    const std::string name = argc == 5 ? argv[4] : "mqtt";
    if (name != "mqtt" && name != "sparkplug") {
        std::fprintf(stderr, "%s: the front is mqtt or sparkplug, not %s\n", argv[0], name.c_str());
        return 2;
    }
    const bool sparkplug = name == "sparkplug";
    mosquitto_lib_init();
    Subscriber subscriber(port, sparkplug);
    Plant plant(parameters);
    const long before = resident_kib();

    gateway::ValueCache cache;
    gateway::Engine engine;
    gateway::DeviceWriter writer(engine, {}, 1s);
    Front front(sparkplug, port, cache, writer, plant);
    const auto connect_by = SteadyClock::now() + 10s;
    while (!front.connected()) {
        if (SteadyClock::now() > connect_by) {
            std::fprintf(stderr, "the %s front did not connect to 127.0.0.1:%d\n", name.c_str(), port);
            return 1;
        }
        std::this_thread::sleep_for(10ms);
    }

    // Memory: the first sample of every parameter, all of it published. Sparkplug sends the
    // first in its births, which the subscriber does not count: the second is its first data.
    long sample = 1;
    plant.sample(cache, sample);
    if (sparkplug) {
        std::this_thread::sleep_for(500ms);
        plant.sample(cache, ++sample);
    }
    if (!subscriber.wait(sample, parameters, 30s)) {
        std::fprintf(stderr, "the first sample did not arrive\n");
        return 1;
    }
    const long after = resident_kib();
    std::printf("%s memory: %.0f KiB per 1000 parameters (cache and front, %zu parameters, resident %ld -> %ld KiB)\n",
                name.c_str(), static_cast<double>(after - before) * 1000.0 / static_cast<double>(parameters), parameters,
                before, after);

    // Latency: 10 samples per second, every parameter changing in each.
    const auto latencies = latencies_ms(subscriber, sample, parameters, seconds, [&](long number) { plant.sample(cache, number); });
    if (latencies.empty()) return 1;
    std::printf("%s latency poll -> subscriber at %zu parameters, 10 samples/s: p50 %.2f ms, p99 %.2f ms, max %.2f ms (%zu values)\n",
                name.c_str(), parameters, percentile(latencies, 0.5), percentile(latencies, 0.99), percentile(latencies, 1.0),
                latencies.size());
    if (!sparkplug) {
        PlainPublisher peer(port, parameters);
        const auto floor = latencies_ms(subscriber, sample, parameters, seconds, [&](long number) { peer.sample(number); });
        if (floor.empty()) return 1;
        std::printf("%s latency plain publisher -> subscriber, the same bursts: p50 %.2f ms, p99 %.2f ms; front/plain p50: %.2f\n",
                    name.c_str(), percentile(floor, 0.5), percentile(floor, 0.99),
                    percentile(latencies, 0.5) / percentile(floor, 0.5));
    }

    // Rate: samples back to back for SECONDS, then until the last has arrived. What counts is
    // what arrived: a front may send only the latest of values that changed faster than it
    // could publish them (the Sparkplug node does), and a host application is owed no more.
    // The poller keeps at most `ahead` samples beyond what has arrived, as mosquitto_pub's input
    // is held back by its pipe: a poller never outruns its lines by millions of values, and one
    // that did would take a core from the broker and the subscriber that the peer's run has.
    constexpr long ahead = 16;
    const auto before_rate = subscriber.total();
    const auto start = SteadyClock::now();
    while (SteadyClock::now() < start + seconds) {
        if (sample > ahead && !subscriber.wait_reached(sample - ahead, 30s)) {
            std::fprintf(stderr, "the front stopped carrying samples (none after %ld)\n", sample - ahead);
            return 1;
        }
        plant.sample(cache, ++sample);
    }
    if (!subscriber.wait(sample, parameters, 120s)) {
        std::fprintf(stderr, "the rate samples did not all arrive\n");
        return 1;
    }
    const double elapsed = std::chrono::duration<double>(subscriber.last_arrival() - start).count();
    const auto changes = static_cast<double>(subscriber.total() - before_rate);
    std::printf("%s rate poller -> broker -> subscriber at %zu parameters: %.0f value changes/s (%.0f in %.2f s)\n",
                name.c_str(), parameters, changes / elapsed, changes, elapsed);
    return 0;
}
