#pragma once
// The running gateway: the lines it owns (one master and one scheduler each) and the Modbus TCP
// front that shares them (docs/DESIGN.md, gateway).
#include <chrono>
#include <functional>
#include <memory>
#include <stop_token>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/gateway_config.hpp"
#include "gateway/history_source.hpp"
#include "gateway/line_scheduler.hpp"
#include "gateway/modbus_tcp_front.hpp"
#include "gateway/poll_groups.hpp"
#include "gateway/reopening_master.hpp"
#include "gateway/value_cache.hpp"
#include "session/slave.hpp"
#include "session/trace.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::gateway {

class LineKeeper;
class HttpListener;
struct HttpLogins;
class SparkplugNode;

// The Sparkplug node kept across a reload that leaves [sparkplug] as it is (Gateway::hand_over_to),
// so that its session goes on: no NDEATH, no NBIRTH (SparkplugNode::release, take_over). The
// holder includes gateway/sparkplug/sparkplug_node.hpp.
struct KeptSparkplug {
    SparkplugConfig config;  // the [sparkplug] it runs
    std::unique_ptr<SparkplugNode> node;
};

struct GatewayOptions {
    session::TraceSink trace;  // every frame on the lines and the front (-v)
    GatewayLog log;            // refused requests and other events worth a line
    // Events that come by the thousand under a flood (Modbus TCP connections closed by the
    // front's limits): for a log at debug level.
    GatewayLog debug_log;
    // Faults on the simulated (virtual-bus) lines' frames, for tests and benchmarks. Called from
    // the writing thread, for the gateway's requests ("gateway") and the simulated devices'
    // replies ("simulated devices") alike: the lines' loop (session/line_loop.hpp), which an
    // injector that takes its time would hold for every line.
    transport::FaultInjector virtual_bus_faults;
    // Also given every sample the gateway's polls take, on the polls' thread (one for every line
    // and poll interval, gateway/poll_groups.hpp): the demo's live table. Must outlive the gateway.
    device::SampleSink* samples = nullptr;
    // With [modbus_tcp] enabled: the front to route the units through, kept by the caller across
    // reloads (it must listen as the configuration asks, ModbusTcpFront::listens_as, and outlive
    // the gateway). None: the gateway opens its own, closed when serve() returns.
    ModbusTcpFront* front = nullptr;
    // The lines kept across reloads (gateway/line_keeper.hpp): the lines this gateway runs as the
    // keeper holds them are taken from it instead of opened, and its loop carries the others; on a
    // reload, hand_over_to() leaves it the lines the next configuration runs alike. None: the
    // gateway opens and closes its own. Must outlive the gateway.
    LineKeeper* lines = nullptr;
    // With [http]: the listening socket the HTTP API accepts on, kept by the caller across
    // reloads (it must listen as [http] listen asks, HttpListener::listens_as, and outlive the
    // gateway). None: the gateway listens itself, and closes the socket when serve() returns.
    HttpListener* http_listener = nullptr;
    // With http_listener: asked when serve() ends whether the next gateway accepts on the same
    // listener (a reload that leaves [http] listen alone). Then the clients' keep-alive
    // connections are parked in it for that gateway instead of closed (HttpServer::stop).
    std::function<bool()> http_listener_kept;
    // With [sparkplug]: where a reload leaves the node for the next gateway, which takes it when
    // its [sparkplug] is the same. None: the node is made and ended with the gateway. Must
    // outlive the gateway.
    KeptSparkplug* sparkplug = nullptr;
    // With [http] users_file: the sessions and failed logins kept across reloads; none: the HTTP
    // API keeps its own, and a reload logs everyone out.
    std::shared_ptr<HttpLogins> http_logins;
    // How serve() waits for its stop: on a condition variable when empty. The gateway command
    // passes its signal handling here (app/stop_signal.hpp, StopSignal::Waits::caller), so the
    // serving thread takes SIGTERM and SIGHUP while it waits and no thread is kept for them.
    // Must return once the token is stopped.
    std::function<void(const std::stop_token&)> wait_for_stop;
    // Called on the engine's loop every `alive_every` while serve() runs, the first time at once:
    // a service manager's watchdog (the gateway command's WATCHDOG=1) hears from the loop itself,
    // so a loop that hangs stops the calls and the manager restarts the service. Zero: never.
    std::function<void()> alive;
    std::chrono::milliseconds alive_every{0};
};

struct LineReport {
    std::string name;
    std::string link;
    LineStatistics statistics;
    // Runs of bytes the line's master threw away: bad CRC or LRC, broken frames, noise.
    std::uint64_t garbled = 0;
    // Whether the line is open now, and how often it went down and was reopened.
    LinkHealth link_health;
};

// The Modbus TCP front's connections (session::TcpConnectionStatistics): accepted, evicted at
// [modbus_tcp] max_connections, refused when every one was busy, closed after idle_timeout.
using FrontReport = session::TcpConnectionStatistics;

class Gateway {
public:
    // Opens every line it can and the Modbus TCP listener. A line whose port cannot be opened
    // starts down and is reopened with back-off (gateway/reopening_master.hpp); the error names
    // a listener that could not be opened or a line configuration no port can take.
    static Result<std::unique_ptr<Gateway>> open(const GatewayConfig& config, GatewayOptions options = {});
    ~Gateway();
    Gateway(const Gateway&) = delete;
    Gateway& operator=(const Gateway&) = delete;

    // The port the Modbus TCP front listens on (the one the kernel chose for port 0); 0 when the
    // front is disabled.
    std::uint16_t modbus_tcp_port() const;

    // The port the OPC UA front listens on (the one taken for port 0); 0 without [opcua].
    std::uint16_t opcua_port() const;

    // The port the HTTP API listens on (the one the kernel chose for port 0); 0 without [http].
    std::uint16_t http_port() const;
    // Reads the HTTP API's certificate and key again (the same files, replaced): see
    // HttpServer::reload_certificate. Any thread.
    Result<void> reload_http_certificate();

    // Records `record` in the audit of writes (its log line and, with [history], its row): a
    // reload's (gateway/config_change.hpp). Any thread.
    void audit(AuditRecord record) const;

    // Serves until `stop` is requested, then drains: the requests already taken are answered
    // (5 s at most) before the front closes, or, when the front is the caller's, holds it
    // (ModbusTcpFront::hold) for the next gateway. Logs each line's statistics every
    // `log.statistics` of the configuration meanwhile. The error when the front failed.
    Result<void> serve(std::stop_token stop);

    std::vector<LineReport> report() const;

    // After serve() returned for a reload, before the gateway is destroyed: hands over to the
    // gateway that `next` opens what both publish (MqttBridge::hand_over), so that it does not
    // flap offline and online across the reload, and, with GatewayOptions::lines, the lines
    // `next` runs alike, which stay open; with GatewayOptions::sparkplug, the Sparkplug node and
    // its session when `next` has the same [sparkplug].
    void hand_over_to(const GatewayConfig& next);

    // The Modbus TCP front's connections so far; all zero when the front is disabled.
    FrontReport front_report() const;

    // The last values the gateway's polls read, per device.
    std::vector<CachedDevice> values() const;

    // The changes the polls find, for the fronts that publish them (gateway/value_cache.hpp):
    // first the state of every device polled so far, then each change, on the poll group's
    // thread. The callback must be quick; the subscription may outlive the gateway.
    [[nodiscard]] ValueSubscription subscribe(ValueCallback callback);

    // The recorded values ([history]) for the HTTP API; nullptr when the configuration has no
    // [history] table. Safe to query from any thread while the gateway runs.
    const HistorySource* history() const;

private:
    struct Parts;
    explicit Gateway(std::unique_ptr<Parts> parts);
    static Result<void> open_alarms(const GatewayConfig& config, Parts& parts, GatewayLog log);
    static Result<void> open_http(const HttpConfig& http, const GatewayConfig& config, HttpListener* listener,
                                  Parts& parts);
    void keep_lines_for(const GatewayConfig& next);
    static void open_sparkplug(const SparkplugConfig& sparkplug, const GatewayConfig& config, Parts& parts, GatewayLog log,
                               KeptSparkplug* kept);
    std::unique_ptr<Parts> parts_;
};

// "line tcp (...): 1234 sent, 1230 answered, 4 timeout(s), ...; busy 12.5 % of the time" for
// the log and the exit summary. With `since`, an earlier report of the same line, the busy
// share is the one since then.
std::string describe(const LineReport& report, const LineReport* since = nullptr);

// "Modbus TCP front: 1100 connection(s) accepted, 1036 closed to admit newer ones, ..." for the
// exit summary.
std::string describe(const FrontReport& report);

// For `--check`: connects once to the history's forward_to, if any, and checks or creates its
// tables; the error says what was wrong (a wrong password, a missing database) and what to do.
// At run time the same failures are a logged retry, never a stop.
Result<void> check_history_forwarding(const GatewayConfig& config);

}  // namespace loopwire::gateway
