// The gateway's MQTT front from the value cache to a subscriber on a real broker (issue 12):
//   rate     value changes/s the bridge carries from the poller's cache to a subscriber, with
//            every parameter changing in every sample, as fast as they go through;
//   latency  poll -> subscriber at 10 samples/s of every parameter (p50, p99, max);
//   memory   resident memory the cache and the bridge take per 1,000 parameters, published.
// The parameters are synthetic (int16, one decimal, "°C"), 50 per device; the samples are what
// the poll groups hand the value cache. Prints one line per figure.
//
// usage: mqtt_throughput PORT PARAMETERS SECONDS   (a mosquitto broker listening on 127.0.0.1:PORT)
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <mosquitto.h>

#include "gateway/device_writer.hpp"
#include "gateway/mqtt_bridge.hpp"
#include "gateway/value_cache.hpp"

namespace {

using namespace loopwire;
using SteadyClock = std::chrono::steady_clock;
using namespace std::chrono_literals;
constexpr std::size_t per_device = 50;
const std::string prefix = "bench/gw";

long resident_kib() {
    std::ifstream status("/proc/self/status");
    std::string line;
    while (std::getline(status, line)) {
        if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
    }
    return 0;
}

// A subscriber to PREFIX/+/+ (the values) that notes when each sample number arrives.
class Subscriber {
public:
    explicit Subscriber(int port) {
        client_ = mosquitto_new(nullptr, true, this);
        mosquitto_message_callback_set(client_, [](mosquitto*, void* self, const mosquitto_message* message) {
            static_cast<Subscriber*>(self)->arrived(*message);
        });
        if (mosquitto_connect(client_, "127.0.0.1", port, 30) != MOSQ_ERR_SUCCESS) throw std::runtime_error("no broker");
        mosquitto_subscribe(client_, nullptr, (prefix + "/+/+").c_str(), 0);
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
        return changed_.wait_for(lock, limit, [&] { return arrivals_[sample] >= count; });
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
    SteadyClock::time_point last_arrival() {
        std::lock_guard lock(mutex_);
        return last_;
    }

private:
    void arrived(const mosquitto_message& message) {
        const auto now = SteadyClock::now();
        const std::string text(static_cast<const char*>(message.payload), static_cast<std::size_t>(message.payloadlen));
        if (std::string_view(message.topic).ends_with("/status")) return;  // PREFIX/DEVICE/status, not a value
        const long sample = std::lround(std::stod(text) * 10);  // the value is the sample number / 10
        std::lock_guard lock(mutex_);
        ++arrivals_[sample];
        last_ = now;
        if (auto found = sent_.find(sample); found != sent_.end()) {
            latencies_.push_back(std::chrono::duration<double, std::milli>(now - found->second).count());
        }
        changed_.notify_all();
    }

    mosquitto* client_ = nullptr;
    std::mutex mutex_;
    std::condition_variable changed_;
    std::map<long, std::size_t> arrivals_;
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
    std::size_t devices() const { return devices_.size(); }
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

double percentile(std::vector<double> values, double share) {
    if (values.empty()) return 0;
    std::sort(values.begin(), values.end());
    return values[std::min(values.size() - 1, static_cast<std::size_t>(share * static_cast<double>(values.size())))];
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 4) {
        std::fprintf(stderr, "usage: %s PORT PARAMETERS SECONDS\n", argv[0]);
        return 2;
    }
    const int port = std::stoi(argv[1]);
    const auto parameters = static_cast<std::size_t>(std::stoul(argv[2]));
    const auto seconds = std::chrono::seconds(std::stoi(argv[3]));
    mosquitto_lib_init();
    Subscriber subscriber(port);
    Plant plant(parameters);
    const long before = resident_kib();

    gateway::ValueCache cache;
    gateway::Engine engine;
    gateway::DeviceWriter writer(engine, {}, 1s);
    gateway::MqttConfig config;
    config.broker = fmt::format("mqtt://127.0.0.1:{}", port);
    config.host = "127.0.0.1";
    config.port = static_cast<std::uint16_t>(port);
    config.prefix = prefix;
    config.republish.reset();
    config.client_id = fmt::format("loopwire-bench-{}", ::getpid());
    gateway::MqttBridge bridge(config, writer, cache, {});
    const auto connect_by = SteadyClock::now() + 10s;
    while (!bridge.connected()) {
        if (SteadyClock::now() > connect_by) {
            std::fprintf(stderr, "the bridge did not connect to 127.0.0.1:%d\n", port);
            return 1;
        }
        std::this_thread::sleep_for(10ms);
    }

    // Memory: the first sample of every parameter, all of it published.
    long sample = 1;
    plant.sample(cache, sample);
    if (!subscriber.wait(sample, parameters, 30s)) {
        std::fprintf(stderr, "the first sample did not arrive\n");
        return 1;
    }
    const long after = resident_kib();
    std::printf("memory: %.0f KiB per 1000 parameters (cache and bridge, %zu parameters, resident %ld -> %ld KiB)\n",
                static_cast<double>(after - before) * 1000.0 / static_cast<double>(parameters), parameters, before, after);

    // Latency: 10 samples per second, every parameter changing in each.
    subscriber.clear();
    const auto latency_end = SteadyClock::now() + seconds;
    while (SteadyClock::now() < latency_end) {
        ++sample;
        subscriber.expect(sample, SteadyClock::now());
        plant.sample(cache, sample);
        std::this_thread::sleep_for(100ms);
    }
    if (!subscriber.wait(sample, parameters, 30s)) {
        std::fprintf(stderr, "the latency samples did not all arrive\n");
        return 1;
    }
    const auto latencies = subscriber.latencies_ms();
    std::printf("latency poll -> subscriber at %zu parameters, 10 samples/s: p50 %.2f ms, p99 %.2f ms, max %.2f ms (%zu values)\n",
                parameters, percentile(latencies, 0.5), percentile(latencies, 0.99), percentile(latencies, 1.0),
                latencies.size());

    // Rate: samples back to back for SECONDS, then until the last has arrived.
    const long first = sample + 1;
    const auto start = SteadyClock::now();
    while (SteadyClock::now() < start + seconds) plant.sample(cache, ++sample);
    if (!subscriber.wait(sample, parameters, 120s)) {
        std::fprintf(stderr, "the rate samples did not all arrive\n");
        return 1;
    }
    const double elapsed = std::chrono::duration<double>(subscriber.last_arrival() - start).count();
    const double changes = static_cast<double>(sample - first + 1) * static_cast<double>(parameters);
    std::printf("rate poller -> broker -> subscriber at %zu parameters: %.0f value changes/s (%.0f in %.2f s)\n", parameters,
                changes / elapsed, changes, elapsed);
    return 0;
}
