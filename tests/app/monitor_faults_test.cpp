// device::run_monitor on a faulty bus (tests/app/faulty_bus_rig.hpp): whatever the line does to the
// frames, a value shown as current is one the device holds, failed polls are counted and said,
// and a unit that stops answering does not slow the healthy one down.
#include <gtest/gtest.h>

#include <cstdio>
#include <ctime>
#include <memory>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "app/monitor_output.hpp"
#include "client/monitor_loop.hpp"
#include "profile/value_format.hpp"
#include "client/faulty_bus_rig.hpp"

namespace loopwire::app {
namespace {

using namespace std::chrono_literals;
using testing::FaultyBusRig;

struct Watched {
    std::size_t device;  // index in the rig
    std::vector<std::pair<std::string, std::string>> values;  // name, constant written first
};

// Writes the constants through the clean bus and returns what the device then holds, as the
// monitor's JSON shows values: label -> name -> value.
nlohmann::json write_constants(FaultyBusRig& rig, const std::vector<Watched>& watched) {
    nlohmann::json expected;
    for (const auto& [index, values] : watched) {
        auto client = rig.clean_client(index);
        std::vector<std::pair<const device::Parameter*, std::string>> assignments;
        std::vector<const device::Parameter*> parameters;
        for (const auto& [name, text] : values) {
            parameters.push_back(client.device().profile->find(name));
            assignments.emplace_back(parameters.back(), text);
        }
        auto written = client.write(assignments);
        EXPECT_TRUE(written.ok()) << (written.ok() ? "" : written.error().message);
        const auto report = client.read(parameters);
        EXPECT_FALSE(report.first_error);
        const std::string label = fmt::format("{}@{}", client.device().profile->id, client.device().unit);
        for (const auto& reading : report.readings) {
            expected[label][reading.parameter->name] = device::value_json(*reading.parameter, *reading.value)["value"];
        }
    }
    return expected;
}

std::vector<device::MonitorTarget> targets_of(FaultyBusRig& rig, const std::vector<Watched>& watched) {
    std::vector<device::MonitorTarget> targets;
    for (const auto& [index, values] : watched) {
        device::MonitorTarget target{&rig.master(), rig.address(index), {}, {}};
        for (const auto& [name, text] : values) target.parameters.push_back(target.device.profile->find(name));
        targets.push_back(std::move(target));
    }
    return targets;
}

// The JSON lines device::run_monitor writes, parsed.
std::vector<nlohmann::json> monitor(const std::vector<device::MonitorTarget>& targets, std::chrono::milliseconds interval, unsigned count) {
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::tmpfile(), &std::fclose);
    device::MonitorSettings settings;
    settings.interval = interval;
    settings.count = count;
    {
        StreamSampleSink sink(file.get(), MonitorFormat::jsonl);
        device::run_monitor(targets, settings, sink, std::stop_token{});
    }
    std::rewind(file.get());
    std::vector<nlohmann::json> rows;
    std::string line;
    for (int c = std::fgetc(file.get()); c != EOF; c = std::fgetc(file.get())) {
        if (c != '\n') {
            line += static_cast<char>(c);
            continue;
        }
        rows.push_back(nlohmann::json::parse(line));
        line.clear();
    }
    return rows;
}

double seconds_of(const std::string& iso) {  // "2026-11-23T10:49:01.123Z" -> seconds of the day
    int hours = 0, minutes = 0;
    double seconds = 0;
    EXPECT_EQ(std::sscanf(iso.c_str() + 11, "%d:%d:%lfZ", &hours, &minutes, &seconds), 3) << iso;
    return hours * 3600.0 + minutes * 60.0 + seconds;
}

const std::vector<Watched> constants{
    {0, {{"set_point", "123"}, {"proportional_band", "45"}, {"alarm_1_threshold", "60"}}},
    {1, {{"set_value", "321"}, {"out1_proportional_band", "77"}}}};

// RTU check bytes (Modbus over serial line V1.02, 2.5.1.2): a frame with an inverted byte is
// discarded, so a corrupted reply is a failed poll, never a current value; a dropped request
// is a timeout. Every value shown must be the constant the device holds.
TEST(MonitorOnFaultyBus, CorruptedOrDroppedFramesNeverShowAWrongCurrentValue) {
    FaultyBusRig rig({"tc10@3", "rampsoak@5"}, 300ms);
    const auto expected = write_constants(rig, constants);
    rig.inject([](const std::string& from, ByteView bytes, unsigned index) {
        // A fixed scramble of the write's index: faults at irregular places, the same every run
        // (a plain period can line up with the polls and hit the same request every time).
        const unsigned roll = (index * 2654435761u >> 16) % 16;
        transport::BusFault fault;
        if (from == "slave" && roll < 2) fault.corrupt_bytes = {bytes.size() / 2};
        if (from == "master" && roll == 2) fault.drop = true;
        if (from == "master" && roll == 3) fault.corrupt_bytes = {1};
        return fault;
    });
    // The polls alone: the identification words a monitor reads with a first poll and after
    // every failed one (client/identity_check.hpp) would add a request to the polls the fixed
    // fault pattern was laid over; identification on a faulty bus is the next test's.
    auto targets = targets_of(rig, constants);
    for (auto& target : targets) target.identify = false;
    const auto rows = monitor(targets, 200ms, 25);
    ASSERT_EQ(rows.size(), 25u);
    for (const auto& [label, values] : expected.items()) {
        unsigned failed = 0, shown = 0;
        for (const auto& row : rows) {
            const auto& device = row["devices"][label];
            const std::string status = device["status"];
            if (status == "no-reply" || status == "partial") ++failed;
            if (status != "ok") {
                EXPECT_FALSE(device["error"].get<std::string>().empty()) << device;
            }
            for (const auto& [name, value] : device["values"].items()) {
                if (value["value"].is_null()) continue;
                ++shown;
                EXPECT_EQ(value["value"], values[name]) << label << " " << name << " in sample " << row["sample"];
            }
        }
        EXPECT_GT(failed, 0u) << label << ": the faults never hit a poll";
        EXPECT_GT(shown, 0u) << label << ": no poll ever got through; last sample: " << rows.back()["devices"][label];
        EXPECT_EQ(rows.back()["devices"][label]["errors"], failed) << label;
    }
}

// A unit that stops answering (its requests dropped once its first polls went through) shows no value from then on (only its age), is counted as
// failing, and is retried with back-off while the healthy unit keeps the 300 ms cadence.
TEST(MonitorOnFaultyBus, UnitThatStopsAnsweringKeepsTheOtherOnCadence) {
    FaultyBusRig rig({"tc10@3", "rampsoak@5"}, 100ms);
    const auto expected = write_constants(rig, constants);
    auto requests_to_5 = std::make_shared<unsigned>(0);
    const auto targets = targets_of(rig, constants);
    const std::size_t blocks = 2;  // rampsoak set_value (word 0) and P1 (word 57): two requests a poll
    rig.inject([requests_to_5, blocks](const std::string& from, ByteView bytes, unsigned) {
        transport::BusFault fault;
        // Its first two polls go through: the first reads its identification word too.
        if (from == "master" && !bytes.empty() && bytes[0] == 5) fault.drop = ++*requests_to_5 > 2 * blocks + 1;
        return fault;
    });
    const auto rows = monitor(targets, 300ms, 10);
    ASSERT_EQ(rows.size(), 10u);
    unsigned tries = 0;
    for (const auto& row : rows) {
        const auto& healthy = row["devices"]["tc10@3"];
        EXPECT_EQ(healthy["status"], "ok") << healthy;
        for (const auto& [name, value] : healthy["values"].items()) EXPECT_EQ(value["value"], expected["tc10@3"][name]) << name;
        const auto& dead = row["devices"]["rampsoak@5"];
        tries += dead["status"] == "no-reply";
        if (row["sample"] == 1) {
            EXPECT_EQ(dead["status"], "ok") << dead;
            continue;
        }
        if (dead["status"] == "ok") {
            EXPECT_EQ(row["sample"], 2) << "answered after it stopped";
            continue;
        }
        EXPECT_TRUE(dead["status"] == "no-reply" || dead["status"] == "waiting") << dead;
        for (const auto& [name, value] : dead["values"].items()) {
            EXPECT_TRUE(value["value"].is_null()) << name << " shown although not read: " << value;
            EXPECT_GT(value["age"].get<double>(), 0.0) << name;
        }
    }
    EXPECT_EQ(rows.back()["devices"]["rampsoak@5"]["errors"], tries);
    EXPECT_GE(tries, 2u);
    EXPECT_LE(tries, 5u) << "retried every sample: no back-off";
    for (std::size_t i = 1; i < rows.size(); ++i) {
        const double gap = seconds_of(rows[i]["time"]) - seconds_of(rows[i - 1]["time"]);
        EXPECT_GE(gap, 0.2) << "sample " << i + 1;
        EXPECT_LE(gap, 0.5) << "sample " << i + 1;
    }
}

}  // namespace
}  // namespace loopwire::app
