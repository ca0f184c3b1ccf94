// The Sparkplug B edge node (gateway/sparkplug/sparkplug_node.hpp) against a real mosquitto
// broker each test starts: a value cache fed with a synthetic device's polls, as the poll
// groups feed it, and a watcher that decodes what the node publishes with protobuf. Births
// before data, seq from 0 in each NBIRTH and +1 per message, DDATA by alias with only what
// changed, DDEATH and DBIRTH again as the device goes silent and comes back, a rebirth on NCMD
// with the same aliases, stale values null with their quality, DCMDs refused in words (a retained
// one always), births held back until the primary host is online, a STATE older than the last
// ignored, and under STATE flaps no NBIRTH with the bdSeq of an NDEATH already sent. Skipped
// without /usr/sbin/mosquitto.
#include "gateway/sparkplug/sparkplug_node.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "gateway/engine.hpp"
#include "gateway/history_store.hpp"
#include "sparkplug/sparkplug_b.pb.h"
#include "support/eventually.hpp"
#include "support/history_test_support.hpp"
#include "support/log_lines.hpp"
#include "support/mosquitto_broker.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using Payload = loopwire::sparkplug::b::Payload;
using loopwire::testing::Broker;
using loopwire::testing::eventually;
using loopwire::testing::Watcher;

const std::string nbirth = "spBv1.0/plant/NBIRTH/edge1";
const std::string ndeath = "spBv1.0/plant/NDEATH/edge1";
const std::string ncmd = "spBv1.0/plant/NCMD/edge1";
const std::string dbirth = "spBv1.0/plant/DBIRTH/edge1/d1";
const std::string ddata = "spBv1.0/plant/DDATA/edge1/d1";
const std::string ddeath = "spBv1.0/plant/DDEATH/edge1/d1";
const std::string dcmd = "spBv1.0/plant/DCMD/edge1/d1";
const std::string host_state = "spBv1.0/STATE/scada";

std::string state(bool online, std::uint64_t timestamp) {
    return fmt::format(R"({{"online": {}, "timestamp": {}}})", online, timestamp);
}

#define SKIP_WITHOUT_BROKER()                                                                             \
    if (!std::filesystem::exists(loopwire::testing::broker_program))                                     \
    GTEST_SKIP() << loopwire::testing::broker_program << " is not installed (Debian package mosquitto)"

loopwire::testing::WatcherOptions every_sparkplug_topic() {
    loopwire::testing::WatcherOptions options;
    options.topics = "spBv1.0/#";
    return options;
}

Payload decoded(const std::optional<std::string>& bytes) {
    Payload payload;
    EXPECT_TRUE(bytes.has_value()) << "no message before the deadline";
    if (bytes) {
        EXPECT_TRUE(payload.ParseFromString(*bytes)) << "not a Sparkplug B payload";
    }
    return payload;
}

const Payload::Metric* named(const Payload& payload, const std::string& name) {
    for (const auto& metric : payload.metrics()) {
        if (metric.name() == name) return &metric;
    }
    return nullptr;
}

// A device of three parameters as a profile would give them: a scaled temperature, a whole
// percentage and a labelled mode.
class Device {
public:
    Device() {
        temperature_.name = "temperature";
        temperature_.type = device::ValueType::int16;
        temperature_.decimals = 1;
        temperature_.unit = "°C";
        power_.name = "power";
        power_.type = device::ValueType::uint16;
        power_.unit = "%";
        power_.writable = true;
        mode_.name = "mode";
        mode_.type = device::ValueType::enumeration;
        mode_.enum_labels = {{0, "auto"}, {1, "manual"}};
        state_ = device::watch("test@1", parameters());
    }
    std::vector<const device::Parameter*> parameters() const { return {&temperature_, &power_, &mode_}; }

    // One poll that answered with these values, sampled now or at `sampled`.
    void answer(ValueCache& cache, double temperature, double power, const std::string& mode,
                std::optional<std::chrono::system_clock::time_point> sampled = std::nullopt) {
        device::ReadReport report;
        add(report, temperature_, temperature, {});
        add(report, power_, power, {});
        add(report, mode_, 0, mode);
        device::record_poll(state_, report, true, "", device::MonitorClock::now());
        cache.update("d1", state_, sampled.value_or(std::chrono::system_clock::now()));
    }
    // One poll that got no reply.
    void silent(ValueCache& cache) {
        device::ReadReport report;
        device::record_poll(state_, report, false, "timeout: no reply within 1 s", device::MonitorClock::now());
        cache.update("d1", state_, std::chrono::system_clock::now());
    }

private:
    static void add(device::ReadReport& report, const device::Parameter& parameter, double number, const std::string& label) {
        device::ParameterReading& reading = report.readings.emplace_back();
        reading.parameter = &parameter;
        reading.value.emplace();
        if (label.empty()) {
            reading.value->value = number;
        } else {
            reading.value->value = label;
        }
        reading.value->unit = parameter.unit;
        reading.value->raw = static_cast<std::uint16_t>(number * 10);
    }

    device::Parameter temperature_;
    device::Parameter power_;
    device::Parameter mode_;
    device::WatchedDevice state_;
};

struct NodeFixture {
    explicit NodeFixture(Broker& broker, const std::string& primary_host = {},
                         std::shared_ptr<Clock> clock = steady_clock(), bool writes = false,
                         const std::filesystem::path& state_file = {},
                         const std::function<void(SparkplugConfig&, SparkplugTiming&)>& adjust = {},
                         SparkplugPending pending = {})
        : cache(std::move(clock)) {
        config.state_file = state_file;
        config.broker = fmt::format("mqtt://127.0.0.1:{}", broker.port());
        config.host = "127.0.0.1";
        config.port = broker.port();
        config.group_id = "plant";
        config.edge_node_id = "edge1";
        config.client_id = "test-edge1";
        config.primary_host = primary_host;
        config.writes = writes;
        SparkplugTiming timing;
        timing.reconnect_first = 50ms;
        timing.reconnect_last = 200ms;
        if (adjust) adjust(config, timing);
        node = std::make_unique<SparkplugNode>(
            config, std::vector<SparkplugDevice>{{"d1", device.parameters()}}, writer, cache,
            [] {
                return std::vector<SparkplugLineFigures>{{"line1", 10, 9, 1, true}};
            },
            log.sink(), timing, nullptr, std::move(pending));
    }

    SparkplugConfig config;
    loopwire::testing::LogLines log;
    Device device;
    ValueCache cache;
    Engine engine;
    DeviceWriter writer{engine, {}, 1s};
    std::unique_ptr<SparkplugNode> node;
};

std::string power_command(std::uint32_t power) {
    Payload command;
    auto* metric = command.add_metrics();
    metric->set_name("power");
    metric->set_datatype(6);
    metric->set_int_value(power);
    return command.SerializeAsString();
}

std::string rebirth_command() {
    Payload command;
    auto* metric = command.add_metrics();
    metric->set_name("Node Control/Rebirth");
    metric->set_datatype(11);
    metric->set_boolean_value(true);
    return command.SerializeAsString();
}

TEST(SparkplugNode, BirthsDataDeathsAndARebirthKeepTheirOrderAndAliases) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    NodeFixture node(broker);

    const Payload node_birth = decoded(watcher.nth(nbirth, 1));
    EXPECT_EQ(node_birth.seq(), 0u);
    const auto* bd_seq = named(node_birth, "bdSeq");
    ASSERT_NE(bd_seq, nullptr);
    EXPECT_EQ(bd_seq->long_value(), 0u);
    ASSERT_NE(named(node_birth, "Node Control/Rebirth"), nullptr);
    ASSERT_NE(named(node_birth, "Lines/line1/Timeouts"), nullptr);
    EXPECT_EQ(named(node_birth, "Lines/line1/Timeouts")->long_value(), 1u);
    EXPECT_EQ(watcher.count(dbirth), 0u) << "no birth before the device answered";

    node.device.answer(node.cache, 21.5, 40, "auto");
    const Payload birth = decoded(watcher.nth(dbirth, 1));
    EXPECT_EQ(birth.seq(), 1u);
    const auto* temperature = named(birth, "temperature");
    const auto* power = named(birth, "power");
    const auto* mode = named(birth, "mode");
    ASSERT_TRUE(temperature && power && mode && named(birth, "Device Control/Last Error"));
    EXPECT_EQ(temperature->datatype(), 10u);  // Double
    EXPECT_DOUBLE_EQ(temperature->double_value(), 21.5);
    EXPECT_EQ(power->datatype(), 6u);  // UInt16
    EXPECT_EQ(power->int_value(), 40u);
    EXPECT_EQ(mode->string_value(), "auto");

    // Only what changed, by alias.
    node.device.answer(node.cache, 22.0, 40, "auto");
    const Payload data = decoded(watcher.nth(ddata, 1));
    EXPECT_EQ(data.seq(), 2u);
    ASSERT_EQ(data.metrics_size(), 1);
    EXPECT_EQ(data.metrics(0).alias(), temperature->alias());
    EXPECT_FALSE(data.metrics(0).has_name());
    EXPECT_DOUBLE_EQ(data.metrics(0).double_value(), 22.0);

    // Silent, then back.
    node.device.silent(node.cache);
    EXPECT_EQ(decoded(watcher.nth(ddeath, 1)).seq(), 3u);
    node.device.answer(node.cache, 22.5, 41, "manual");
    const Payload again = decoded(watcher.nth(dbirth, 2));
    EXPECT_EQ(again.seq(), 4u);
    EXPECT_DOUBLE_EQ(named(again, "temperature")->double_value(), 22.5);

    // A rebirth asked for: everything again from seq 0, the same session's bdSeq, the same aliases.
    watcher.publish(ncmd, rebirth_command());
    const Payload reborn = decoded(watcher.nth(nbirth, 2));
    EXPECT_EQ(reborn.seq(), 0u);
    EXPECT_EQ(named(reborn, "bdSeq")->long_value(), 0u);
    const Payload device_reborn = decoded(watcher.nth(dbirth, 3));
    EXPECT_EQ(device_reborn.seq(), 1u);
    for (const auto& metric : birth.metrics()) {
        const auto* same = named(device_reborn, metric.name());
        ASSERT_NE(same, nullptr) << metric.name();
        EXPECT_EQ(same->alias(), metric.alias()) << metric.name();
    }
}

// bdSeq counts on across restarts (Sparkplug 3.0): each run's node keeps the next one in its
// state file before it connects; a file that holds no bdSeq is said and counting starts at 0.
TEST(SparkplugNode, BdSeqCountsOnAcrossRestartsThroughItsStateFile) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    const loopwire::testing::TempFolder folder("loopwire-sparkplug");
    const auto file = folder.path / "sparkplug.state";
    for (std::uint64_t run = 0; run < 3; ++run) {
        NodeFixture node(broker, {}, steady_clock(), false, file);
        EXPECT_EQ(named(decoded(watcher.nth(nbirth, run + 1)), "bdSeq")->long_value(), run) << "run " << run;
    }  // each run's node leaves with its NDEATH
    std::ifstream kept(file);
    std::string text;
    std::getline(kept, text);
    EXPECT_EQ(text, "bdSeq 3");

    std::ofstream(file) << "not a number\n";
    NodeFixture spoiled(broker, {}, steady_clock(), false, file);
    EXPECT_EQ(named(decoded(watcher.nth(nbirth, 4)), "bdSeq")->long_value(), 0u);
    EXPECT_TRUE(spoiled.log.wait_for("does not hold a bdSeq"));
}

TEST(SparkplugNode, AStaleValueIsNullWithItsQualityNeverItsOldNumber) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    auto clock = std::make_shared<VirtualClock>();
    NodeFixture node(broker, {}, clock);
    node.cache.expect_polls("d1", 1s);
    node.device.answer(node.cache, 21.5, 40, "auto");
    ASSERT_TRUE(watcher.nth(dbirth, 1));
    clock->advance(4s);  // the poll due after 1 s is overdue by more than two intervals
    ASSERT_EQ(node.cache.mark_overdue(), std::vector<std::string>{"d1"});
    const Payload data = decoded(watcher.nth(ddata, 1));
    ASSERT_EQ(data.metrics_size(), 3);  // the three values; the last error did not change
    for (const auto& metric : data.metrics()) {
        EXPECT_TRUE(metric.is_null()) << metric.alias();
        EXPECT_EQ(metric.value_case(), Payload::Metric::VALUE_NOT_SET);
        ASSERT_EQ(metric.properties().keys_size(), 1);
        EXPECT_EQ(metric.properties().keys(0), "Quality");
        EXPECT_EQ(metric.properties().values(0).int_value(), 500u);
    }
    EXPECT_EQ(watcher.count(ddeath), 0u) << "stale is not dead: its values are null, the device is still born";
}

TEST(SparkplugNode, CommandsTheNodeCannotTakeAreRefusedInWords) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    NodeFixture node(broker);  // writes off
    node.device.answer(node.cache, 21.5, 40, "auto");
    const Payload birth = decoded(watcher.nth(dbirth, 1));

    Payload command;
    auto* metric = command.add_metrics();
    metric->set_name("power");
    metric->set_datatype(6);
    metric->set_int_value(55);
    watcher.publish(dcmd, command.SerializeAsString());
    const Payload refusal = decoded(watcher.nth(ddata, 1));
    ASSERT_EQ(refusal.metrics_size(), 1);
    EXPECT_EQ(refusal.metrics(0).alias(), named(birth, "Device Control/Last Error")->alias());
    EXPECT_THAT(refusal.metrics(0).string_value(), HasSubstr("writes are off"));

    // Bytes that are not protobuf, and a device the node does not have: logged, nothing sent.
    watcher.publish(dcmd, std::string("\xff\xfe\x01 not protobuf", 16));
    watcher.publish("spBv1.0/plant/DCMD/edge1/nosuch", command.SerializeAsString());
    EXPECT_TRUE(node.log.wait_for("not a Sparkplug B payload"));
    EXPECT_TRUE(node.log.wait_for("no such device of this node"));
    EXPECT_FALSE(node.log.has("\xff")) << "a peer's bytes reach the log escaped";
    EXPECT_EQ(watcher.count(ddata), 1u);
}

// The gateway's one write policy (gateway/device_writer.hpp): a DCMD to a device its polls find
// silent is refused at once, in the words every front gives, and never reaches a line.
TEST(SparkplugNode, ACommandToASilentDeviceIsRefusedAtOnceInTheWritersWords) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    NodeFixture node(broker, {}, steady_clock(), true);
    node.writer.refuse_silent(node.cache.device_lookup());
    node.device.answer(node.cache, 21.5, 40, "auto");
    ASSERT_TRUE(watcher.nth(dbirth, 1));
    node.device.silent(node.cache);
    ASSERT_TRUE(watcher.nth(ddeath, 1));
    const std::string words = node.writer.refusal("d1").value().message;
    EXPECT_THAT(words, HasSubstr("device \"d1\" does not answer its polls"));
    watcher.publish(dcmd, power_command(55));
    EXPECT_TRUE(node.log.wait_for("DCMD to d1 refused: " + words));
}

TEST(SparkplugNode, BirthsWaitForThePrimaryHostAndADeathFollowsItsGoingOffline) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    NodeFixture node(broker, "scada");
    node.device.answer(node.cache, 21.5, 40, "auto");
    ASSERT_TRUE(node.log.wait_for("waiting for primary host scada"));
    EXPECT_EQ(watcher.count(nbirth), 0u);
    EXPECT_EQ(watcher.count(dbirth), 0u);

    watcher.publish("spBv1.0/STATE/scada", R"({"online": true, "timestamp": 1})", true);
    EXPECT_EQ(named(decoded(watcher.nth(nbirth, 1)), "bdSeq")->long_value(), 0u);
    ASSERT_TRUE(watcher.nth(dbirth, 1));

    // Offline: the node's own death, then a new session that waits again.
    watcher.publish("spBv1.0/STATE/scada", R"({"online": false, "timestamp": 2})", true);
    EXPECT_EQ(named(decoded(watcher.nth(ndeath, 1)), "bdSeq")->long_value(), 0u);
    ASSERT_TRUE(node.log.wait_for("bdSeq 1"));
    EXPECT_EQ(watcher.count(nbirth), 1u);
    watcher.publish("spBv1.0/STATE/scada", R"({"online": true, "timestamp": 3})", true);
    EXPECT_EQ(named(decoded(watcher.nth(nbirth, 2)), "bdSeq")->long_value(), 1u);
}

// Store and forward: while the primary host is offline (the node dead, disconnected) the DDATA
// it would have sent is kept, at most max_stored values, the oldest dropped and counted; once
// the host is back, after the NBIRTH and DBIRTH, it comes in its order with is_historical and
// the samples' own timestamps, but for the value the DBIRTH carries already.
TEST(SparkplugNode, WhatChangedWhileDeadFollowsTheBirthsAsHistoricalInItsOrder) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    NodeFixture node(broker, "scada", steady_clock(), false, {}, [](SparkplugConfig& config, SparkplugTiming& timing) {
        config.store_and_forward = 1min;
        timing.max_stored = 3;
    });
    watcher.publish(host_state, state(true, 1), true);
    node.device.answer(node.cache, 21.5, 40, "auto");
    ASSERT_TRUE(watcher.nth(dbirth, 1));
    watcher.publish(host_state, state(false, 2), true);
    ASSERT_TRUE(watcher.nth(ndeath, 1));

    // Polls 100 ms apart (their own times: the test answers faster than that).
    const std::vector<double> temperatures{22.0, 22.5, 23.0, 23.5};
    const auto first = std::chrono::system_clock::now();
    const auto sampled = [&first](std::size_t i) { return first + i * 100ms; };
    for (std::size_t i = 0; i < 3; ++i) {
        node.device.answer(node.cache, temperatures[i], 40, "auto", sampled(i));
        ASSERT_TRUE(eventually([&] { return node.node->stored() == i + 1; })) << "value " << i << " not kept";
    }
    node.device.answer(node.cache, temperatures[3], 40, "auto", sampled(3));
    ASSERT_TRUE(node.log.wait_for("store and forward holds 3 values, its most"));

    watcher.publish(host_state, state(true, 3), true);
    ASSERT_TRUE(watcher.nth(nbirth, 2));
    const Payload birth = decoded(watcher.nth(dbirth, 2));
    const auto* born = named(birth, "temperature");
    ASSERT_NE(born, nullptr);
    ASSERT_TRUE(watcher.nth(ddata, 1));
    ASSERT_TRUE(node.log.wait_for("store and forward: 2 values of the outage forwarded as historical in 2 DDATA (1 already in "
                                  "the births, 0 of devices not born now, 0 older than 60 s and 1 over the most of 3 dropped)"));
    ASSERT_TRUE(watcher.nth(ddata, 2));  // published before the line above: arrived by now or soon
    std::vector<double> historical;
    std::uint64_t last_timestamp = 0;
    for (const auto& [topic, bytes] : watcher.arrived([](const std::string& topic) { return topic == ddata; })) {
        Payload data;
        ASSERT_TRUE(data.ParseFromString(bytes));
        for (const auto& metric : data.metrics()) {
            EXPECT_TRUE(metric.is_historical());
            EXPECT_EQ(metric.alias(), born->alias());
            EXPECT_GT(metric.timestamp(), last_timestamp) << "out of order";
            EXPECT_LT(metric.timestamp(), born->timestamp()) << "the birth's own value sent again";
            last_timestamp = metric.timestamp();
            historical.push_back(metric.double_value());
        }
    }
    // 22.0 was the oldest over the most; 23.5 is the birth's.
    EXPECT_EQ(historical, (std::vector<double>{22.5, 23.0}));
    EXPECT_DOUBLE_EQ(born->double_value(), 23.5);
    EXPECT_EQ(node.node->stored(), 0u);
}

// Store and forward with a history file: what one run kept while dead and could not forward is
// in the file when it stops (table sparkplug_pending, with each value's kind and quality); the
// next run forwards it as historical once the device is born (its polls answer after the
// NBIRTH), each value once, and the file is emptied of it.
TEST(SparkplugNode, WhatAStoppedRunKeptInTheHistoryFileTheNextRunForwardsAfterTheBirth) {
    SKIP_WITHOUT_BROKER();
    loopwire::testing::TempFolder folder("loopwire-sparkplug");
    HistoryOptions options;
    options.database = folder.path / "plant.db";
    auto store = HistoryStore::open(options);
    ASSERT_TRUE(store) << store.error().message;  // no writer thread: write_pending() below
    const auto with_store_and_forward = [](SparkplugConfig& config, SparkplugTiming&) {
        config.store_and_forward = 1min;
    };
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    const std::vector<double> temperatures{22.0, 22.5, 23.0};
    const auto first = std::chrono::system_clock::now() - 1s;
    {
        NodeFixture run(broker, "scada", steady_clock(), false, {}, with_store_and_forward,
                        sparkplug_pending_in(**store));
        watcher.publish(host_state, state(true, 1), true);
        run.device.answer(run.cache, 21.5, 40, "auto");
        ASSERT_TRUE(watcher.nth(dbirth, 1));
        watcher.publish(host_state, state(false, 2), true);
        ASSERT_TRUE(watcher.nth(ndeath, 1));
        for (std::size_t i = 0; i < temperatures.size(); ++i) {
            run.device.answer(run.cache, temperatures[i], i == 2 ? 41 : 40, "auto", first + i * 100ms);
            ASSERT_TRUE(eventually([&] { return run.node->stored() >= i + 1; })) << "value " << i << " not kept";
        }
    }
    ASSERT_TRUE((*store)->write_pending());
    auto kept = load_sparkplug_pending(options.database);
    ASSERT_TRUE(kept) << kept.error().message;
    ASSERT_EQ(kept->size(), 4u);  // three temperatures, and the power with the last
    EXPECT_EQ((*kept)[0].metric, "temperature");
    EXPECT_EQ((*kept)[0].sample.value, sparkplug::MetricValue{22.0});
    EXPECT_EQ((*kept)[3].metric, "power");
    EXPECT_EQ((*kept)[3].sample.value, sparkplug::MetricValue{std::uint64_t{41}});

    const std::size_t births_before = watcher.arrived([](const std::string& topic) { return topic == dbirth; }).size();
    SparkplugPending pending = sparkplug_pending_in(**store);
    pending.loaded = std::move(*kept);
    watcher.publish(host_state, state(true, 3), true);
    NodeFixture next(broker, "scada", steady_clock(), false, {}, with_store_and_forward, std::move(pending));
    ASSERT_TRUE(next.log.wait_for("store and forward: 4 values the last run kept"));
    ASSERT_TRUE(watcher.nth(nbirth, 2));
    EXPECT_EQ(next.node->stored(), 4u) << "forwarded before the device was born";
    next.device.answer(next.cache, 24.0, 42, "manual");
    const Payload birth = decoded(watcher.nth(dbirth, births_before + 1));
    ASSERT_TRUE(next.log.wait_for("store and forward: 4 values of the outage forwarded as historical in 3 DDATA"))
        << ::testing::PrintToString(next.log.all());
    ASSERT_TRUE(watcher.nth(ddata, 3)) << "the forwarded DDATA did not arrive";
    std::vector<double> historical;
    std::vector<std::uint32_t> powers;
    for (const auto& [topic, bytes] : watcher.arrived([](const std::string& topic) { return topic == ddata; })) {
        Payload data;
        ASSERT_TRUE(data.ParseFromString(bytes));
        for (const auto& metric : data.metrics()) {
            EXPECT_TRUE(metric.is_historical());
            EXPECT_LT(metric.timestamp(), named(birth, "temperature")->timestamp());
            if (metric.has_double_value()) historical.push_back(metric.double_value());
            if (metric.has_int_value()) powers.push_back(metric.int_value());
        }
    }
    EXPECT_EQ(historical, temperatures);
    EXPECT_EQ(powers, std::vector<std::uint32_t>{41});
    EXPECT_EQ(next.node->stored(), 0u);
    ASSERT_TRUE((*store)->write_pending());
    auto left = load_sparkplug_pending(options.database);
    ASSERT_TRUE(left);
    EXPECT_TRUE(left->empty()) << left->size() << " values would be forwarded again by a third run";
}

// A reload that keeps [sparkplug] hands the node, connected, to the next gateway: no NDEATH, no
// NBIRTH; a device gone dies (DDEATH), one added back is born with the aliases it had.
TEST(SparkplugNode, TakenOverAcrossAReloadTheSessionGoesOnAndOnlyTheDevicesThatChangedAreTold) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    NodeFixture node(broker);
    node.device.answer(node.cache, 21.5, 40, "auto");
    const Payload birth = decoded(watcher.nth(dbirth, 1));
    const auto lines = [] { return std::vector<SparkplugLineFigures>{{"line1", 10, 9, 1, true}}; };

    ASSERT_TRUE(node.node->release());
    ValueCache next_cache;
    node.node->take_over({}, node.writer, next_cache, lines, node.log.sink(), nullptr);
    EXPECT_EQ(decoded(watcher.nth(ddeath, 1)).seq(), birth.seq() + 1) << "the session's seq goes on";

    ASSERT_TRUE(node.node->release());
    ValueCache last_cache;
    node.node->take_over({{"d1", node.device.parameters()}}, node.writer, last_cache, lines, node.log.sink(), nullptr);
    node.device.answer(last_cache, 22.0, 40, "auto");
    const Payload again = decoded(watcher.nth(dbirth, 2));
    ASSERT_NE(named(again, "temperature"), nullptr);
    EXPECT_EQ(named(again, "temperature")->alias(), named(birth, "temperature")->alias());
    EXPECT_EQ(watcher.count(nbirth), 1u);
    EXPECT_EQ(watcher.count(ndeath), 0u);
    node.node.reset();  // before the caches it reads
}

// A DCMD published with the retain flag is refused whether it comes live (the node subscribes
// with MQTT 5's "retain as published") or as the copy the broker hands over at every
// subscription: it never reaches the writer, and Device Control/Last Error says why, at once and
// again after a reconnection. A live DCMD still goes to the writer.
TEST(SparkplugNode, ARetainedCommandIsRefusedLiveAndAfterEveryReconnection) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    NodeFixture node(broker, "scada", steady_clock(), true);
    watcher.publish(host_state, state(true, 1), true);
    node.device.answer(node.cache, 21.5, 40, "auto");
    const Payload birth = decoded(watcher.nth(dbirth, 1));
    const auto* last_error = named(birth, "Device Control/Last Error");
    ASSERT_NE(last_error, nullptr);
    EXPECT_EQ(last_error->string_value(), "");
    const std::string refused_retained = "DCMD to d1 refused: published with the retain flag";

    watcher.publish(dcmd, power_command(55), true);
    const Payload refusal = decoded(watcher.nth(ddata, 1));
    ASSERT_EQ(refusal.metrics_size(), 1);
    EXPECT_EQ(refusal.metrics(0).alias(), last_error->alias());
    EXPECT_THAT(refusal.metrics(0).string_value(), HasSubstr("published with the retain flag"));
    EXPECT_TRUE(node.log.has(refused_retained));
    // A retained NCMD is refused as well: a rebirth asked for once is not asked again at every
    // reconnection.
    watcher.publish(ncmd, rebirth_command(), true);
    EXPECT_TRUE(node.log.wait_for("NCMD refused: published with the retain flag"));
    EXPECT_FALSE(node.log.has("rebirth asked for"));
    EXPECT_EQ(watcher.count(nbirth), 1u);

    // A live one goes to the writer (which knows no device here, and says so in its own words).
    watcher.publish(dcmd, power_command(60));
    const Payload live = decoded(watcher.nth(ddata, 2));
    ASSERT_EQ(live.metrics_size(), 1);
    EXPECT_THAT(live.metrics(0).string_value(), ::testing::Not(HasSubstr("retain")));

    // A new session (the host went away and came back): the broker hands the retained DCMD over
    // at the subscription, and it is refused again, never written.
    watcher.publish(host_state, state(false, 2), true);
    ASSERT_TRUE(watcher.nth(ndeath, 1));
    watcher.publish(host_state, state(true, 3), true);
    ASSERT_TRUE(watcher.nth(nbirth, 2));
    EXPECT_TRUE(eventually([&] { return node.log.count(refused_retained) >= 2; }))
        << "the retained DCMD was not refused after the reconnection";
    EXPECT_EQ(node.log.count("DCMD to d1 refused"), 3) << "every DCMD but the live one was refused as retained";
}

TEST(SparkplugNode, AStateOlderThanTheLastTakenChangesNothing) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    NodeFixture node(broker, "scada");
    watcher.publish(host_state, state(true, 1000), true);
    ASSERT_TRUE(watcher.nth(nbirth, 1));

    // Late: an offline of before the online already taken says nothing of the host now.
    watcher.publish(host_state, state(false, 500), true);
    ASSERT_TRUE(node.log.wait_for("STATE of 500 ignored"));
    EXPECT_EQ(watcher.count(ndeath), 0u);
    EXPECT_TRUE(node.node->connected());

    // A newer one is taken.
    watcher.publish(host_state, state(false, 2000), true);
    EXPECT_EQ(named(decoded(watcher.nth(ndeath, 1)), "bdSeq")->long_value(), 0u);
}

// The host's STATE flapping 100 times, 20 ms apart: every NBIRTH carries the bdSeq of its own
// session's will, one more than the NDEATH before it (never the bdSeq of a death already sent),
// every NDEATH the bdSeq of the NBIRTH before it, and no death is sent twice.
TEST(SparkplugNode, UnderStateFlapsEachBirthCarriesItsOwnSessionsBdSeq) {
    SKIP_WITHOUT_BROKER();
    Broker broker;
    Watcher watcher(broker.port(), every_sparkplug_topic());
    auto node = std::make_unique<NodeFixture>(broker, "scada");
    constexpr int flaps = 100;
    for (int i = 0; i <= flaps; ++i) {
        watcher.publish(host_state, state(i % 2 == 0, static_cast<std::uint64_t>(i + 1)), true);
        std::this_thread::sleep_for(20ms);  // the flaps' pace, not a wait for anything
    }
    // The last word is online: once the broker has it, the node ends born after it.
    ASSERT_TRUE(watcher.nth(host_state, flaps + 1));
    const auto born_after_the_last_state = [&] {
        const auto order =
            watcher.arrived([](const std::string& topic) { return topic == host_state || topic == nbirth; });
        const auto last_state =
            std::find_if(order.rbegin(), order.rend(), [](const auto& m) { return m.first == host_state; });
        return last_state != order.rbegin();
    };
    ASSERT_TRUE(eventually(born_after_the_last_state)) << "no NBIRTH after the host's last STATE (online)";
    node.reset();  // a clean stop: its NDEATH, acknowledged
    const std::string marker = "spBv1.0/plant/TEST/edge1";
    watcher.publish(marker, "after the node's last message");
    ASSERT_TRUE(watcher.nth(marker, 1));

    const auto order = watcher.arrived([](const std::string& topic) { return topic == nbirth || topic == ndeath; });
    std::optional<std::pair<bool, std::uint64_t>> last;  // (a birth?, its bdSeq)
    int births = 0;
    for (const auto& [topic, bytes] : order) {
        const Payload payload = decoded(bytes);
        const auto* bd_seq = named(payload, "bdSeq");
        ASSERT_NE(bd_seq, nullptr) << topic;
        const std::uint64_t number = bd_seq->long_value();
        const bool birth = topic == nbirth;
        const std::string story =
            fmt::format("{} bdSeq {} after {}", birth ? "NBIRTH" : "NDEATH", number,
                        last ? fmt::format("{} bdSeq {}", last->first ? "NBIRTH" : "NDEATH", last->second)
                             : std::string("nothing"));
        if (birth) {
            ++births;
            if (!last) {
                EXPECT_EQ(number, 0u) << story;
            } else if (last->first) {
                EXPECT_EQ(number, last->second) << story << ": a rebirth keeps its session's bdSeq";
            } else {
                EXPECT_EQ(number, (last->second + 1) % 256) << story << ": a new session's will carries the next bdSeq";
            }
        } else if (last && last->first) {
            EXPECT_EQ(number, last->second) << story << ": a death carries its session's bdSeq";
        } else if (last) {
            EXPECT_NE(number, last->second) << story << ": one death sent twice";
        }
        last = {birth, number};
    }
    EXPECT_GE(births, 2) << "the flaps made no new session";
    EXPECT_TRUE(last && !last->first) << "the clean stop's NDEATH is the last";
}

}  // namespace
}  // namespace loopwire::gateway
