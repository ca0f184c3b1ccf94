// The gateway's service life (gateway/service.hpp): SIGHUP's reload keeps the running
// configuration when the new one does not load, applies a new log level in place, and restarts
// the gateway for anything else; a reloaded configuration that cannot be served gives way to the
// one before it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/socket.h>

#include <algorithm>
#include <condition_variable>
#include <fstream>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "gateway/config_change.hpp"
#include "gateway/gateway.hpp"
#include "gateway/service.hpp"
#include "support/eventually.hpp"
#include "support/history_test_support.hpp"
#include "support/loopback_client.hpp"
#include "support/loopback_listener.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::gateway {
namespace {

using loopwire::testing::eventually;
using namespace std::chrono_literals;
using ::testing::HasSubstr;

const device::ProfileRegistry& profiles() { return device::testing::builtin_registry(); }

// One TC10 simulated on a virtual line; `extra` ends the file (the [modbus_tcp] table).
std::string plant(const std::string& poll, const std::string& level = "info", const std::string& modbus_tcp = "enabled = false\n") {
    return fmt::format(R"toml(
[log]
level = "{}"

[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200&parity=none"
timeout = "500ms"

[[lines.devices]]
name = "oven1"
device = "tc10@3"
poll = "{}"
parameters = ["measured_value"]

[modbus_tcp]
{})toml",
                       level, poll, modbus_tcp);
}

// Every line each part of the service logged, and the levels it was told to apply.
struct RecordedLog {
    std::mutex mutex;
    std::vector<std::string> info, warning;
    std::vector<LogConfig::Level> levels;

    ServiceLog log() {
        ServiceLog log;
        log.info = [this](const std::string& line) { add(info, line); };
        log.warning = [this](const std::string& line) { add(warning, line); };
        log.debug = [](const std::string&) {};
        log.set_level = [this](LogConfig::Level level) {
            std::lock_guard lock(mutex);
            levels.push_back(level);
        };
        return log;
    }
    void add(std::vector<std::string>& lines, const std::string& line) {
        std::lock_guard lock(mutex);
        lines.push_back(line);
    }
};

// Stops `stop` after a minute unless destroyed first, so a service that never stops fails its
// test instead of hanging it.
class Watchdog {
public:
    explicit Watchdog(std::stop_source& stop)
        : thread_([&stop](std::stop_token own) {
              std::mutex mutex;
              std::condition_variable_any woken;
              std::unique_lock lock(mutex);
              if (!woken.wait_for(lock, own, 60s, [] { return false; }) && !own.stop_requested()) {
                  ADD_FAILURE() << "the service was still serving after a minute";
                  stop.request_stop();
              }
          }) {}

private:
    std::jthread thread_;
};

class GatewayService : public ::testing::Test {
protected:
    void write(const std::string& text) { std::ofstream(file, std::ios::binary | std::ios::trunc) << text; }
    GatewayConfig load() {
        auto config = load_gateway_config(file, profiles());
        EXPECT_TRUE(config) << config.error().message;
        return *config;
    }

    // Serves the file, reloads and all, until `stop` (a minute at most); the outcome.
    Result<void> serve(ConfigReloads& reloads, std::stop_source& stop, const ServiceHooks& hooks, const GatewayOptions& options = {}) {
        Watchdog watchdog(stop);
        return serve_with_reloads(load(), options, reloads, stop.get_token(), recorded.log(), hooks);
    }

    testing::TempFolder folder{"loopwire-service"};
    std::string file = (folder.path / "gateway.toml").string();
    RecordedLog recorded;
};

TEST_F(GatewayService, AReloadThatDoesNotLoadKeepsTheRunningConfiguration) {
    write(plant("100ms"));
    ConfigReloads reloads(file, profiles(), recorded.log());
    const auto round = reloads.start_round(load());
    write("[[lines]]\nname = 3\n");
    reloads.hangup();
    EXPECT_FALSE(round.stop_requested());
    EXPECT_FALSE(reloads.next());
    ASSERT_EQ(recorded.warning.size(), 1u);
    EXPECT_THAT(recorded.warning[0], HasSubstr("configuration not reloaded, the running one is kept: " + file));
}

TEST_F(GatewayService, ANewLogLevelAppliesInPlace) {
    write(plant("100ms"));
    ConfigReloads reloads(file, profiles(), recorded.log());
    const auto round = reloads.start_round(load());
    write(plant("100ms", "debug"));
    reloads.hangup();
    EXPECT_FALSE(round.stop_requested());
    EXPECT_EQ(recorded.levels, std::vector<LogConfig::Level>{LogConfig::Level::debug});
    ASSERT_EQ(recorded.info.size(), 1u);
    EXPECT_THAT(recorded.info[0], HasSubstr("re-read: only the log level changed"));
    reloads.hangup();  // the same file again: now nothing changed
    EXPECT_THAT(recorded.info.at(1), HasSubstr("re-read: nothing changed"));
}

TEST_F(GatewayService, AnyOtherChangeStopsTheRoundAndHandsTheConfigurationOver) {
    write(plant("100ms"));
    ConfigReloads reloads(file, profiles(), recorded.log());
    const auto round = reloads.start_round(load());
    write(plant("200ms"));
    reloads.hangup();
    EXPECT_TRUE(round.stop_requested());
    ASSERT_TRUE(reloads.next());
    auto taken = reloads.take();
    ASSERT_TRUE(taken);
    EXPECT_EQ(taken->lines.at(0).devices.at(0).poll, 200ms);
    EXPECT_FALSE(reloads.take());
}

// Each reload leaves one audit record: who asked (SIGHUP), what changed in words and how it
// ended. One that changes nothing the gateway runs, or does not load, is recorded by the running
// gateway at once; one that restarts it is handed to the next round's gateway, refused when
// that one cannot be opened.
TEST_F(GatewayService, EveryReloadIsAuditedWithWhatItChanged) {
    write(plant("100ms"));
    ConfigReloads reloads(file, profiles(), recorded.log());
    std::vector<AuditRecord> audited;
    const auto round = reloads.start_round(load());
    reloads.while_serving({}, [&audited](AuditRecord record) { audited.push_back(std::move(record)); });
    write("[[lines]]\nname = 3\n");
    reloads.hangup();
    write(plant("100ms", "debug"));
    reloads.hangup();
    ASSERT_EQ(audited.size(), 2u);
    EXPECT_EQ(audited[0].origin.front, "reload");
    EXPECT_EQ(audited[0].origin.peer, "SIGHUP");
    EXPECT_EQ(audited[0].parameter, "configuration " + file);
    EXPECT_EQ(audited[0].new_value, "none: the file does not load");
    EXPECT_THAT(audited[0].outcome, HasSubstr("refused: " + file));
    EXPECT_EQ(audited[0].outcome.find('\n'), std::string::npos);  // the mistakes on one line
    EXPECT_EQ(audited[1].new_value, "[log] changed");
    EXPECT_EQ(audited[1].outcome, "confirmed");
    EXPECT_EQ(audit_line(audited[1]), "audit: reload SIGHUP: configuration " + file + ": [log] changed: confirmed");
    EXPECT_FALSE(reloads.take_reload_record());

    write(plant("200ms", "debug"));
    reloads.hangup();
    EXPECT_TRUE(round.stop_requested());
    EXPECT_EQ(audited.size(), 2u);  // the next round's gateway records it
    reloads.reload_refused("cannot be served (port taken)");
    auto handed = reloads.take_reload_record();
    ASSERT_TRUE(handed);
    EXPECT_EQ(handed->new_value, "device oven1 changed");
    EXPECT_EQ(handed->outcome, "refused: cannot be served (port taken)");
    EXPECT_NE(handed->time, std::chrono::system_clock::time_point{});  // when it was asked for
    EXPECT_FALSE(reloads.take_reload_record());
}

TEST(ConfigChange, NamesTheLinesDevicesAndTablesAddedRemovedOrChanged) {
    GatewayConfig before;
    before.lines.resize(2);
    before.lines[0].name = "furnace";
    before.lines[0].devices.resize(2);
    before.lines[0].devices[0].name = "oven";
    before.lines[0].devices[1].name = "kiln";
    before.lines[1].name = "bench";
    EXPECT_EQ(describe_config_change(before, before), "nothing changed");
    GatewayConfig after = before;
    after.lines.pop_back();
    after.lines.emplace_back().name = "dock";
    after.lines[0].devices.pop_back();
    after.lines[0].devices.emplace_back().name = "dryer";
    after.lines[0].devices[0].poll = std::chrono::milliseconds(200);
    after.lines[0].timeout = std::chrono::milliseconds(300);
    after.modbus_tcp.enabled = false;
    after.mqtt.emplace();
    after.http.emplace();
    before.history.emplace();
    EXPECT_EQ(describe_config_change(before, after),
              "line bench removed (0 devices); line dock added (0 devices); device kiln removed from line furnace; "
              "device dryer added to line furnace; device oven changed; line furnace changed; [modbus_tcp] disabled; "
              "[mqtt] added; [http] added; [history] removed");
}


// A port something else listens on: a Modbus TCP front cannot open there.
using TakenPort = testing::LoopbackListener;

TEST_F(GatewayService, AReloadThatCannotBeServedGivesWayToThePreviousConfiguration) {
    TakenPort taken;
    write(plant("100ms"));
    ConfigReloads reloads(file, profiles(), recorded.log());
    std::stop_source stop;
    std::vector<std::chrono::milliseconds> served;  // the poll of each configuration served, in order
    unsigned reloading = 0;
    ServiceHooks hooks;
    // Each reload is asked for while a gateway serves, as SIGHUP would: first to a configuration
    // whose Modbus TCP front cannot listen, then to one that works; then the service is stopped.
    hooks.serving = [&](const GatewayConfig& config, const Gateway&) {
        served.push_back(config.lines.at(0).devices.at(0).poll);
        if (served.size() == 1) write(plant("100ms", "info", fmt::format("enabled = true\nlisten = \"127.0.0.1:{}\"\n", taken.port())));
        if (served.size() == 2) write(plant("200ms"));
        if (served.size() < 3) reloads.hangup();
        else stop.request_stop();
    };
    hooks.reloading = [&reloading] { ++reloading; };
    // The gateways' own log: the audit's lines of the two reloads.
    RecordedLog gateways;
    GatewayOptions options;
    options.log = [&gateways](const std::string& line) {
        if (line.find("audit: reload") != std::string::npos) gateways.add(gateways.info, line);
    };
    auto result = serve(reloads, stop, hooks, options);
    ASSERT_TRUE(result) << result.error().message;
    EXPECT_EQ(served, (std::vector<std::chrono::milliseconds>{100ms, 100ms, 200ms}));
    // The one that could not be served is recorded, refused, by the gateway that runs again.
    ASSERT_EQ(gateways.info.size(), 2u);
    EXPECT_THAT(gateways.info[0], HasSubstr("[modbus_tcp] enabled: refused: cannot be served ("));
    EXPECT_THAT(gateways.info[1], HasSubstr(": device oven1 changed: confirmed"));
    EXPECT_EQ(reloading, 2u);
    ASSERT_EQ(recorded.warning.size(), 1u);
    EXPECT_THAT(recorded.warning[0], HasSubstr("the reloaded configuration cannot be served"));
    EXPECT_THAT(recorded.warning[0], HasSubstr("going back to the previous one"));
}

// A reload that leaves a line alone keeps it open - the line's figures go on
// from where they were, its polls carry on, it never goes down - and one that changes the line
// (here its timeout) opens it afresh.
TEST_F(GatewayService, AReloadKeepsTheLinesItLeavesAloneOpen) {
    write(plant("100ms"));
    ConfigReloads reloads(file, profiles(), recorded.log());
    std::stop_source stop;
    std::vector<LineStatistics> at_start;  // each round's line, as the round began
    std::vector<LineStatistics> at_end;    // and once it had polled a while
    std::vector<LinkHealth> health;
    ServiceHooks hooks;
    hooks.serving = [&](const GatewayConfig&, const Gateway& gateway) {
        at_start.push_back(gateway.report().at(0).statistics);
        const auto answered_before = at_start.back().answered;
        const bool polled = eventually([&] { return gateway.report().at(0).statistics.answered >= answered_before + 3; }, 30s);
        EXPECT_TRUE(polled) << "round " << at_start.size() << ": the line's polls were not answered";
        at_end.push_back(gateway.report().at(0).statistics);
        health.push_back(gateway.report().at(0).link_health);
        if (at_start.size() == 1) write(plant("200ms"));  // the device's poll only: the line stays
        if (at_start.size() == 2) {
            std::string retimed = plant("200ms");
            retimed.replace(retimed.find("timeout = \"500ms\""), 17, "timeout = \"400ms\"");
            write(retimed);
        }
        if (at_start.size() < 3 && polled) reloads.hangup();
        else stop.request_stop();
    };
    std::vector<std::string> gateway_log;
    std::mutex gateway_log_mutex;
    GatewayOptions options;
    options.log = [&](const std::string& line) {
        std::lock_guard lock(gateway_log_mutex);
        gateway_log.push_back(line);
    };
    auto result = serve(reloads, stop, hooks, options);
    ASSERT_TRUE(result) << result.error().message;
    ASSERT_EQ(at_start.size(), 3u);
    // Kept: the second round's line begins with the first one's figures, never down between.
    EXPECT_GE(at_start[1].sent, at_end[0].sent);
    EXPECT_GE(at_start[1].answered, at_end[0].answered);
    EXPECT_EQ(health[1].down_periods, health[0].down_periods);
    EXPECT_TRUE(health[1].up);
    // Retimed: a new line, its figures from nothing.
    EXPECT_LT(at_start[2].sent, at_end[1].sent);
    std::lock_guard lock(gateway_log_mutex);
    EXPECT_EQ(std::count_if(gateway_log.begin(), gateway_log.end(),
                            [](const std::string& line) { return line.find("stays open across the reload") != std::string::npos; }),
              1)
        << "the log said which line stayed open, once";
}

// A reload that leaves [http] listen alone keeps the HTTP API's listening
// socket: the port stays (here one the kernel chose), and a client that connects while the next
// gateway opens is answered by it. Before, the port was closed between the two and then another.
TEST_F(GatewayService, AReloadKeepsTheHttpApiListening) {
    const std::string http = "enabled = false\n\n[http]\nlisten = \"127.0.0.1:0\"\n";
    write(plant("100ms", "info", http));
    ConfigReloads reloads(file, profiles(), recorded.log());
    std::stop_source stop;
    std::vector<std::uint16_t> ports;
    std::unique_ptr<testing::LoopbackClient> between;  // connected while no gateway serves
    std::string answer;
    ServiceHooks hooks;
    hooks.serving = [&](const GatewayConfig&, const Gateway& gateway) {
        ports.push_back(gateway.http_port());
        if (ports.size() == 1) {
            write(plant("200ms", "info", http));  // the poll changes: the gateway is reopened
            reloads.hangup();
            return;
        }
        if (between) answer = between->ask("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
        stop.request_stop();
    };
    hooks.reloading = [&] { between = std::make_unique<testing::LoopbackClient>(ports.at(0)); };
    auto result = serve(reloads, stop, hooks);
    ASSERT_TRUE(result) << result.error().message;
    ASSERT_EQ(ports.size(), 2u);
    EXPECT_EQ(ports[1], ports[0]) << "the port moved across the reload";
    ASSERT_TRUE(between && between->connected()) << "the port was closed while the configuration was reloaded";
    EXPECT_THAT(answer, HasSubstr("HTTP/1.1 200")) << answer;
    EXPECT_THAT(answer, HasSubstr("oven1"));
    std::lock_guard lock(recorded.mutex);
    EXPECT_EQ(std::count_if(recorded.info.begin(), recorded.info.end(),
                            [](const std::string& line) { return line.find("HTTP API kept listening on port") != std::string::npos; }),
              1);
}

// A reload that leaves [http] listen alone keeps the clients' keep-alive
// connections: a client that asked before the reload asks again on the same connection after it,
// even with half of its next request sent while the gateway reloaded. An event stream ends (it
// followed the old gateway's values; EventSource reconnects). Before, every connection was closed.
TEST_F(GatewayService, AReloadKeepsTheHttpClientsConnections) {
    const std::string http = "enabled = false\n\n[http]\nlisten = \"127.0.0.1:0\"\n";
    write(plant("100ms", "info", http));
    ConfigReloads reloads(file, profiles(), recorded.log());
    std::stop_source stop;
    std::unique_ptr<testing::LoopbackClient> client, stream;
    std::string before, after, closing, stream_head;
    ssize_t stream_end = 1;
    int rounds = 0;
    ServiceHooks hooks;
    hooks.serving = [&](const GatewayConfig&, const Gateway& gateway) {
        if (++rounds == 1) {
            client = std::make_unique<testing::LoopbackClient>(gateway.http_port());
            stream = std::make_unique<testing::LoopbackClient>(gateway.http_port());
            before = client->ask_once("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
            stream_head = stream->ask_some("GET /api/events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
            client->send("GET /api/dev");  // the rest after the reload
            std::string renamed = plant("100ms", "info", http);  // the device changes: the gateway is reopened
            renamed.replace(renamed.find("oven1"), 5, "oven2");
            write(renamed);
            reloads.hangup();
            return;
        }
        after = client->ask_once("ices/oven2 HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
        closing = client->ask("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
        stream_end = stream->read_until_closed();
        stop.request_stop();
    };
    auto result = serve(reloads, stop, hooks);
    ASSERT_TRUE(result) << result.error().message;
    ASSERT_EQ(rounds, 2);
    EXPECT_THAT(before, HasSubstr("HTTP/1.1 200")) << before;
    EXPECT_THAT(stream_head, HasSubstr("text/event-stream")) << stream_head;
    EXPECT_THAT(after, HasSubstr("HTTP/1.1 200")) << "the connection did not outlive the reload: '" << after << "'";
    EXPECT_THAT(after, HasSubstr("\"oven2\"")) << "not answered by the reloaded gateway";
    EXPECT_THAT(closing, HasSubstr("HTTP/1.1 200")) << closing;
    EXPECT_EQ(stream_end, 0) << "the event stream was neither ended at the reload nor timed out";
}

// A reload that moves [http] listen closes the connections of the old address: nothing serves
// them there any more.
TEST_F(GatewayService, AReloadThatMovesTheHttpApiClosesItsConnections) {
    write(plant("100ms", "info", "enabled = false\n\n[http]\nlisten = \"127.0.0.1:0\"\n"));
    ConfigReloads reloads(file, profiles(), recorded.log());
    std::stop_source stop;
    std::unique_ptr<testing::LoopbackClient> client;
    std::string before, after = "not asked";
    int rounds = 0;
    ServiceHooks hooks;
    hooks.serving = [&](const GatewayConfig&, const Gateway& gateway) {
        if (++rounds == 1) {
            client = std::make_unique<testing::LoopbackClient>(gateway.http_port());
            before = client->ask_once("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
            write(plant("100ms", "info", "enabled = false\n\n[http]\nlisten = \"localhost:0\"\n"));
            reloads.hangup();
            return;
        }
        after = client->ask_once("GET /api/devices HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
        stop.request_stop();
    };
    auto result = serve(reloads, stop, hooks);
    ASSERT_TRUE(result) << result.error().message;
    ASSERT_EQ(rounds, 2);
    EXPECT_THAT(before, HasSubstr("HTTP/1.1 200")) << before;
    EXPECT_EQ(after, "") << "a connection of the old address was still answered";
}

TEST_F(GatewayService, AFirstConfigurationThatCannotBeServedIsAnError) {
    TakenPort taken;
    write(plant("100ms", "info", fmt::format("enabled = true\nlisten = \"127.0.0.1:{}\"\n", taken.port())));
    ConfigReloads reloads(file, profiles(), recorded.log());
    std::stop_source stop;
    auto result = serve(reloads, stop, {});
    EXPECT_FALSE(result);
}

}  // namespace
}  // namespace loopwire::gateway
