#pragma once
// The gateway's configuration: one TOML file naming the lines the gateway owns, the devices on
// each, and the fronts it serves (docs/DESIGN.md, gateway). Every error names the file, the
// line and the key, and says what is expected.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/alarms/alarm_engine.hpp"
#include "client/device_client.hpp"
#include "common/result.hpp"
#include "gateway/http_users.hpp"
#include "profile/profile_registry.hpp"
#include "transport/address_allow_list.hpp"
#include "transport/link_url.hpp"

// Equality of the link and device types the configuration holds, for reload_needs_restart
// below (found by argument-dependent lookup from the defaulted comparisons).
namespace loopwire::transport {
bool operator==(const SerialSettings& a, const SerialSettings& b);
bool operator==(const LinkUrl& a, const LinkUrl& b);
}  // namespace loopwire::transport
namespace loopwire::device {
bool operator==(const DeviceAddress& a, const DeviceAddress& b);  // the same profile object, unit and numbering
}  // namespace loopwire::device

namespace loopwire::gateway {

struct DeviceConfig {
    std::string name;                       // used in MQTT topics, URLs and logs
    device::DeviceAddress address;          // profile and unit on its line
    std::uint8_t tcp_unit = 0;              // the unit id Modbus TCP clients use (default: the device's unit)
    std::chrono::milliseconds poll{1000};   // interval of the parameters polled
    std::vector<std::string> parameters;    // empty: the profile's default watch list
    // Whether its polls check the unit is that device (client/identity_check.hpp) at start and
    // after every outage; a unit that answers as another is `wrong-device`, none of its values kept.
    bool identify = true;

    bool operator==(const DeviceConfig&) const = default;
};

// A line with no hardware behind it (link "rtu:virtual?baud=19200", or ascii:virtual): the
// gateway simulates its devices on an in-process virtual bus that spends wire time as a real
// line at that speed would (transport/virtual_bus.hpp). For trying the gateway, demos and tests.
struct LineSimulation {
    double speed = 1.0;      // process seconds per real second, as `simulate --speed`
    std::uint64_t seed = 1;  // measurement noise, as `simulate --seed`

    bool operator==(const LineSimulation&) const = default;
};

struct LineConfig {
    std::string name;
    transport::LinkUrl link;
    std::optional<LineSimulation> simulation;  // set exactly when the link is a virtual bus
    std::chrono::milliseconds timeout{1000};
    unsigned retries = 0;
    // After a request that got no usable reply, the next waits until the line has been quiet this
    // long, so a late reply is never taken for it (session::MasterOptions). nullopt: the timeout.
    std::optional<std::chrono::milliseconds> late_reply_window;
    // Requests on the wire at once (LineSchedulerOptions::max_in_flight): more than 1 only on a
    // Modbus TCP line ("tcp://"), whose replies carry the request's transaction id.
    std::size_t max_in_flight = 1;
    std::vector<DeviceConfig> devices;
    std::string link_written_at;  // "plant.toml:7", for what check_environment finds of the port

    // Where the link was written is not part of what the line does: a reload that only moves it
    // keeps the line open.
    bool operator==(const LineConfig& other) const {
        return name == other.name && link == other.link && simulation == other.simulation && timeout == other.timeout &&
               retries == other.retries && late_reply_window == other.late_reply_window &&
               max_in_flight == other.max_in_flight && devices == other.devices;
    }
};

struct ModbusTcpConfig {
    bool enabled = true;
    std::string host = "127.0.0.1";  // loopback unless the file names another address
    std::uint16_t port = 1502;
    bool writes = true;              // false: writes are refused with exception 1 and logged
    // Reads (function codes 1-4) answered from the line's reply to the same request up to this
    // old (gateway/read_cache.hpp); 0: off, every request goes to the line.
    std::chrono::milliseconds max_age{0};
    // Clients connected at once: a newcomer past it is admitted by closing the idlest
    // connection (session::TcpClientLimits), so idle sockets cannot lock out a working client.
    std::size_t max_connections = 64;
    // A connection with nothing received and no request in progress for this long is closed;
    // zero ("off"): never.
    std::chrono::milliseconds idle_timeout{60000};
    // Client addresses served (others are closed at accept, counted), and those whose writes
    // are passed on (others get exception 01h); empty: every address.
    transport::AddressAllowList allow;
    transport::AddressAllowList write_allow;

    bool operator==(const ModbusTcpConfig&) const = default;
};

struct LogConfig {
    enum class Level { debug, info, warning, error };
    Level level = Level::info;
    // How often each line's statistics are logged; zero: only when the gateway stops.
    std::chrono::milliseconds statistics{60000};

    bool operator==(const LogConfig&) const = default;
};

// [mqtt]: the gateway publishes its values to a broker and takes writes from it
// (gateway/mqtt_bridge.hpp), over plain TCP (mqtt://) or TLS (mqtts://).
struct MqttTls {
    std::filesystem::path ca_file;    // empty: the system's certificate store (/etc/ssl/certs)
    std::filesystem::path cert_file;  // the gateway's own certificate and key, for brokers that
    std::filesystem::path key_file;   // ask clients for one; both or neither

    bool operator==(const MqttTls&) const = default;
};

struct MqttConfig {
    std::string broker;               // as written, "mqtt://127.0.0.1:1883", for messages
    std::string host;
    std::uint16_t port = 1883;
    std::optional<MqttTls> tls;       // set exactly for mqtts://
    std::string username;             // empty: no credentials sent
    std::string password;             // read from `password_file`, never written in the TOML
    std::string prefix = "loopwire/gateway";  // topic levels without '+', '#' or empty levels
    bool writes = false;              // `PREFIX/DEVICE/PARAMETER/set` refused unless true
    std::string client_id;            // empty: the broker gets "loopwire-" and the prefix
    // Every value is published when it changes and again at least this often; none: only on
    // changes (and on each connection).
    std::optional<std::chrono::milliseconds> republish = std::chrono::minutes(5);
    enum class Discovery { none, homeassistant };
    Discovery discovery = Discovery::none;
    std::string discovery_prefix = "homeassistant";
    // The gateway's name in discovery ids: [gateway] name, else the prefix's last level.
    std::string gateway_name = "gateway";
    // The dashboard's address in the discovery documents' device blocks (configuration_url):
    // http://HOST:PORT/ of [http] when it is enabled, else empty (no link).
    std::string configuration_url;
    // A .../set payload longer than this many bytes is refused unread (a value is a few bytes).
    std::size_t max_payload = 1024;

    bool operator==(const MqttConfig&) const = default;
};

// [sparkplug]: the gateway as a Sparkplug B edge node (gateway/sparkplug/sparkplug_node.hpp).
// The broker keys (broker, TLS files, username, password_file) are [mqtt]'s.
struct SparkplugConfig {
    std::string broker;  // as written, for messages
    std::string host;
    std::uint16_t port = 1883;
    std::optional<MqttTls> tls;
    std::string username;
    std::string password;
    std::string client_id;     // empty: "loopwire-sparkplug-" GROUP "-" EDGE
    std::string group_id;      // spBv1.0/GROUP/...: one topic level
    std::string edge_node_id;  // default: the gateway's name, else "loopwire"
    std::string primary_host;  // empty: births go out at once, with no host application to wait for
    bool writes = false;       // DCMD writes refused unless true
    std::size_t max_payload = 64 * 1024;  // a longer NCMD or DCMD is refused unread
    // Where the node keeps the bdSeq of its next session, so that it counts on across restarts
    // (Sparkplug 3.0, bdSeq); resolved against the configuration file's folder. Empty: counted
    // from 0 at each start.
    std::filesystem::path state_file;
    // Store and forward (Sparkplug 3.0): while the broker cannot be reached (or the primary host
    // is offline) the DDATA the node would have sent is kept for at most this long, and sent
    // after the next births as historical. None: what changes meanwhile is lost.
    std::optional<std::chrono::milliseconds> store_and_forward;

    bool operator==(const SparkplugConfig&) const = default;
};

// [history]: every change of a polled value, and a heartbeat sample of each, kept in an SQLite
// file for the HTTP API's charts (gateway/history_store.hpp).
struct HistoryConfig {
    // As written; a relative path is taken from the configuration file's folder, so the
    // gateway finds the same file whatever folder it is started from (`~` is not expanded).
    std::string database_as_written;
    std::filesystem::path database;  // resolved
    std::chrono::seconds keep = std::chrono::hours(24 * 90);
    std::chrono::milliseconds heartbeat{60000};
    // A PostgreSQL historian the history is forwarded to (gateway/history_forwarder.hpp), as
    // libpq takes it: "postgresql://user@host:5432/plant", "postgresql:///plant?host=/run/pg" or
    // "host=/var/run/postgresql dbname=plant"; TLS by its sslmode. Empty: not forwarded. The
    // SQLite `database` stays the gateway's own history and is the buffer the forwarder ships from.
    std::string forward_to;
    std::string password;  // read from `password_file`; empty: the URL's, PGPASSFILE's, or none
    std::string written_at;  // "plant.toml:13", for what check_environment finds

    // Where the key was written is not part of what the history does: a reload that only moves
    // it keeps the history open.
    bool operator==(const HistoryConfig& other) const {
        return database_as_written == other.database_as_written && database == other.database && keep == other.keep &&
               heartbeat == other.heartbeat && forward_to == other.forward_to && password == other.password;
    }
};

// [http]: the HTTP API and the dashboard (gateway/http_server.hpp). Reads need no token on a
// loopback address; writes always need one, and without `token_file` they are refused.
struct HttpConfig {
    std::string host = "127.0.0.1";  // loopback unless the file names another address
    std::uint16_t port = 8080;       // 0: any free port (tests)
    std::string token_file;          // empty: writes refused
    std::string token;               // the file's first line, read when the configuration is
    // Users who log in (gateway/http_users.hpp), read from `users_file` when the configuration
    // is; none: the token alone guards the API.
    std::string users_file;
    std::vector<HttpUser> users;
    // With users: who reads without a session or token (loopback: clients on a loopback address).
    enum class OpenReads { loopback, none, all };
    OpenReads open_reads = OpenReads::loopback;
    std::chrono::milliseconds session_timeout = std::chrono::hours(8);  // idle
    // A client that has not sent a whole request this long after it began is closed.
    std::chrono::milliseconds read_timeout{10000};
    // A client that has not sent a request's header this long after it connected, or after the
    // response before, is closed (the shorter of this and read_timeout counts).
    std::chrono::milliseconds header_timeout{5000};
    unsigned max_connections = 64;
    // Connections one client address may hold at once: a few clients cannot take every slot.
    unsigned max_connections_per_client = 8;
    // Event streams (which stay open) may take only a share of those, so that requests always
    // find room: by default half of each, and always fewer than them.
    unsigned max_event_streams = 32;
    unsigned max_event_streams_per_client = 4;
    // An event stream whose client has taken nothing of what waits for it this long is closed.
    std::chrono::milliseconds send_timeout{10000};
    // Host header names answered besides the listen address, localhost, 127.0.0.1 and [::1]
    // (the names a browser uses to reach the gateway; any other is refused 421, which keeps a
    // page of another site from reading the API through DNS rebinding). Lower case.
    std::vector<std::string> hosts;
    // Client addresses served; others are closed at accept, counted. Empty: every address.
    transport::AddressAllowList allow;
    // HTTPS: the server's certificate and its private key, PEM files (both or neither). The same
    // names across a reload re-read them: new connections get the files' new certificate.
    std::string certificate;
    std::string private_key;

    // Whether the address is loopback (127.0.0.0/8, ::1, localhost): only then are reads open.
    bool loopback() const;

    bool operator==(const HttpConfig&) const = default;
};

// [opcua]: the OPC UA front (gateway/opcua/opcua_server.hpp): every polled parameter a variable
// under Objects/GATEWAY/LINE/DEVICE, written through the same write policy as every front.
struct OpcuaConfig {
    std::string listen = "opc.tcp://127.0.0.1:4840";  // as written, for messages
    std::string host = "127.0.0.1";
    std::uint16_t port = 4840;  // 0: any free port, said in the log and /api/health
    bool writes = false;        // a Write is answered Bad_NotWritable unless true
    bool anonymous = true;      // whether sessions without a user are taken
    std::string application_name;  // empty: "loopwire GATEWAY" (or "loopwire")
    std::string application_uri;   // empty: "urn:loopwire:GATEWAY" (or "urn:loopwire")
    unsigned max_sessions = 100;
    unsigned max_subscriptions = 1000;      // over every session
    unsigned max_monitored_items = 100000;  // over every subscription

    bool operator==(const OpcuaConfig&) const = default;
};

struct GatewayConfig {
    std::string source;  // the file it came from, for messages
    std::string name;    // [gateway] name: in MQTT's default prefix and discovery ids; may be empty
    std::vector<LineConfig> lines;
    ModbusTcpConfig modbus_tcp;
    LogConfig log;
    std::optional<MqttConfig> mqtt;  // absent [mqtt] table: no MQTT
    std::optional<SparkplugConfig> sparkplug;  // absent [sparkplug] table: no Sparkplug B
    std::optional<HistoryConfig> history;  // absent [history] table: no history
    std::optional<HttpConfig> http;  // absent [http] table: no HTTP API
    std::optional<OpcuaConfig> opcua;  // absent [opcua] table: no OPC UA
    std::vector<alarms::LimitAlarm> alarm_limits;  // [[alarms.limits]]

    bool operator==(const GatewayConfig&) const = default;
};

// Whether `link` names the in-process virtual bus rather than a device file.
bool is_virtual_bus(const transport::LinkUrl& link);

// Parses and checks a configuration; `source` names it in errors ("plant.toml"). The error
// lists every mistake found, one a line in the file's order, then their count when there are
// several ("6 mistakes in plant.toml"); a file that is not TOML gives its syntax error alone.
Result<GatewayConfig> parse_gateway_config(std::string_view text, const std::string& source,
                                           const device::ProfileRegistry& profiles);
Result<GatewayConfig> load_gateway_config(const std::filesystem::path& file, const device::ProfileRegistry& profiles);

// Whether serving `next` in place of `running` needs the gateway restarted: not when the two
// differ at most in the log level, which applies at once (a SIGHUP from logrotate, or for a
// file saved again unchanged, keeps every line, listener, connection and MQTT session up).
bool reload_needs_restart(const GatewayConfig& running, const GatewayConfig& next);

// What one poll of the device reads: the configured names, or the profile's default watch list.
std::vector<const device::Parameter*> polled_parameters(const DeviceConfig& device);

// What the configuration needs of this machine that parsing does not look at: the history
// database's folder exists and can be written. An error names the file, line and key and what to
// do; `--check` fails on it, and the gateway does not start.
Result<void> check_environment(const GatewayConfig& config);

// What `loopwire gateway --check` prints: each line with its devices, poll groups and the
// estimated share of the line's wire time the polls take.
std::string describe_plan(const GatewayConfig& config);

}  // namespace loopwire::gateway
