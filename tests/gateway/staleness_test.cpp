// A device whose poll stops coming back (a line too busy to carry it), in virtual time: once
// the poll is more than two intervals overdue, its values read `stale` in the value cache, the
// HTTP API, /metrics, the MQTT documents and the change stream, the history writes no heartbeat
// of the frozen value, and the next poll makes everything `ok` again (gateway/value_cache.hpp).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <map>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "gateway/history_schema.hpp"
#include "gateway/history_store.hpp"
#include "gateway/http_api.hpp"
#include "gateway/metrics.hpp"
#include "gateway/mqtt_documents.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using Json = nlohmann::json;
using SystemClock = std::chrono::system_clock;

// Only parsed: the line is never opened here; the test plays the poller.
const char* const plant = R"toml(
[[lines]]
name = "plant"
link = "rtu:virtual?baud=19200&parity=none"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "1s"
parameters = ["measured_value", "set_point"]

[modbus_tcp]
enabled = false
)toml";

// 2026-01-01T00:00:00Z.
const SystemClock::time_point t0 = SystemClock::time_point(std::chrono::seconds(1767225600));

struct TempFolder {
    std::filesystem::path path;
    TempFolder() {
        std::string pattern = (std::filesystem::temp_directory_path() / "loopwire-stale-XXXXXX").string();
        path = mkdtemp(pattern.data());
    }
    ~TempFolder() { std::filesystem::remove_all(path); }
};

class Staleness : public ::testing::Test {
protected:
    void SetUp() override {
        auto parsed = parse_gateway_config(plant, "plant.toml", device::testing::builtin_registry());
        ASSERT_TRUE(parsed) << parsed.error().message;
        config = std::move(*parsed);
        polled = polled_parameters(config.lines[0].devices[0]);
        state = device::watch("tc10@3", polled);
        cache.expect_polls("oven", 1s);

        HistoryOptions options;
        options.database = folder.path / "plant.db";
        options.heartbeat = 2s;
        options.wall_clock = wall_clock();
        auto opened = HistoryStore::open(std::move(options));
        ASSERT_TRUE(opened) << opened.error().message;
        history = std::move(*opened);
        recording = cache.subscribe([this](const ValueChange& change) {
            history->record(change);
            if (!change.about_device()) last_told[change.parameter] = change;
        });
        HttpApiSources sources;
        sources.cache = &cache;
        sources.lines = [] { return std::vector<LineReport>{{"plant", "rtu:virtual", {}, 0, {}}}; };
        api = std::make_unique<HttpApi>(config, std::move(sources));
    }

    ValueCache::WallClock wall_clock() const {
        return [ms = wall_ms] { return SystemClock::time_point(std::chrono::milliseconds(ms->load())); };
    }
    SystemClock::time_point wall_now() const { return wall_clock()(); }

    // Virtual time passes on both clocks; the staleness timer looks, and the history writes.
    void pass(std::chrono::milliseconds length) {
        clock->advance(length);
        wall_ms->fetch_add(length.count());
        (void)cache.mark_overdue();
        ASSERT_TRUE(history->write_pending());
    }

    // One poll that read the measured value `tenths` and a set point of 137.5.
    void poll(std::uint16_t tenths) {
        device::ReadReport report;
        report.readings.push_back({polled[0], device::EngineeringValue{tenths / 10.0, "ok", tenths, "°C"}, ""});
        report.readings.push_back({polled[1], device::EngineeringValue{137.5, "ok", 1375, "°C"}, ""});
        device::record_poll(state, report, true, "", device::MonitorClock::now());
        cache.update("oven", state, wall_now());
        ASSERT_TRUE(history->write_pending());
    }

    Json detail() {
        HttpRequest request;
        request.method = "GET";
        request.path = "/api/devices/oven";
        request.host = "localhost";
        const HttpOutcome outcome = api->handle(request);
        EXPECT_EQ(outcome.response.status, 200u) << outcome.response.body;
        return Json::parse(outcome.response.body);
    }

    // One parameter of the device's detail.
    static Json parameter_in(const Json& device, const std::string& name) {
        for (const auto& parameter : device["parameters"]) {
            if (parameter["name"] == name) return parameter;
        }
        ADD_FAILURE() << "no parameter " << name << " in " << device.dump();
        return Json::object();
    }

    std::string metrics() {
        HttpRequest request;
        request.method = "GET";
        request.path = "/metrics";
        request.host = "localhost";
        return api->handle(request).response.body;
    }

    std::int64_t rows_after(SystemClock::time_point time) {
        auto db = history::open_for_reading(folder.path / "plant.db");
        EXPECT_TRUE(db) << db.error().message;
        const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(time.time_since_epoch()).count();
        auto count = db->query_integer(fmt::format("SELECT count(*) FROM samples WHERE t > {}", ms));
        EXPECT_TRUE(count) << count.error().message;
        return count ? *count : -1;
    }

    std::string last_status_of(const std::string& parameter) {
        auto db = history::open_for_reading(folder.path / "plant.db");
        EXPECT_TRUE(db) << db.error().message;
        auto status = db->query_text(fmt::format(
            "SELECT coalesce(s.status, 'ok') FROM samples s JOIN series r ON r.id = s.series_id WHERE r.parameter = '{}' "
            "ORDER BY s.t DESC LIMIT 1",
            parameter));
        EXPECT_TRUE(status) << status.error().message;
        return status ? *status : "";
    }

    TempFolder folder;
    GatewayConfig config;
    std::vector<const device::Parameter*> polled;
    device::WatchedDevice state;
    std::shared_ptr<VirtualClock> clock = std::make_shared<VirtualClock>();
    std::shared_ptr<std::atomic<std::int64_t>> wall_ms = std::make_shared<std::atomic<std::int64_t>>(
        std::chrono::duration_cast<std::chrono::milliseconds>(t0.time_since_epoch()).count());
    ValueCache cache{clock, wall_clock()};
    std::unique_ptr<HistoryStore> history;
    std::map<std::string, ValueChange> last_told;
    ValueSubscription recording;  // after the store and the map it fills: ends first
    std::unique_ptr<HttpApi> api;
};

TEST_F(Staleness, AnOverdueValueIsStaleEverywhereAndNotAHeartbeatUntilTheNextPoll) {
    // Polled every second for 2 s, then the polls stop coming back.
    poll(3550);
    pass(1s);
    poll(3550);
    pass(1s);
    poll(3550);
    const auto last_poll = wall_now();
    pass(2s);  // a heartbeat of the value that holds still, as it is still current
    EXPECT_EQ(rows_after(last_poll), 2);
    EXPECT_EQ(detail()["status"], "ok");
    pass(1s);  // 3 s since the last poll: due after 1 s, overdue by 2 intervals, no more
    EXPECT_EQ(detail()["status"], "ok");

    pass(1ms);
    const auto stale_at = wall_now();
    // The HTTP API: the device and its values stale, the last value kept with its age.
    const Json device = detail();
    EXPECT_EQ(device["status"], "stale");
    EXPECT_NE(device["error"].get<std::string>().find("not polled for 3.0 s (polled every 1.0 s)"), std::string::npos)
        << device["error"];
    const Json measured = parameter_in(device, "measured_value");
    EXPECT_EQ(measured["status"], "stale");
    EXPECT_EQ(measured["value"], 355.0);
    EXPECT_NE(measured["error"].get<std::string>().find("not polled for"), std::string::npos);
    EXPECT_NE(metrics().find("loopwire_device_status{device=\"oven\",status=\"stale\"} 1"), std::string::npos);
    EXPECT_NE(metrics().find("loopwire_line_devices_stale{line=\"plant\"} 1"), std::string::npos);

    // The change stream, and the MQTT documents made from it: stale, with no value to show.
    const ValueChange& told = last_told.at("measured_value");
    EXPECT_EQ(told.status, "stale");
    EXPECT_FALSE(told.value);
    const Json meta = meta_document(told, polled[0], told.error);
    EXPECT_EQ(meta["status"], "stale");
    EXPECT_NE(meta["error"].get<std::string>().find("not polled for"), std::string::npos);

    // The history: a row that says so, then no heartbeat of the frozen value however long.
    EXPECT_EQ(last_status_of("measured_value"), "stale");
    for (int i = 0; i < 30; ++i) pass(1s);
    EXPECT_EQ(rows_after(stale_at), 0) << "a heartbeat repeated a stale value";

    // The next poll: ok everywhere again, and heartbeats of the new value.
    poll(3970);
    const Json again = detail();
    EXPECT_EQ(again["status"], "ok");
    EXPECT_EQ(parameter_in(again, "measured_value")["status"], "ok");
    EXPECT_EQ(parameter_in(again, "measured_value")["value"], 397.0);
    EXPECT_EQ(parameter_in(again, "set_point")["status"], "ok");
    EXPECT_EQ(last_told.at("measured_value").status, "ok");
    EXPECT_EQ(last_told.at("set_point").text, "137.5");
    EXPECT_EQ(meta_document(last_told.at("measured_value"), polled[0], "")["status"], "ok");
    EXPECT_EQ(last_status_of("measured_value"), "ok");
    EXPECT_NE(metrics().find("loopwire_device_status{device=\"oven\",status=\"ok\"} 1"), std::string::npos);
    const auto polled_again = wall_now();
    pass(1s);
    poll(3970);
    pass(1s);
    EXPECT_EQ(rows_after(polled_again), 2) << "the heartbeats of the fresh value";
}

}  // namespace
}  // namespace loopwire::gateway
