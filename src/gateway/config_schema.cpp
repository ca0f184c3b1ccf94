#include "gateway/config_schema.hpp"

#include <array>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

namespace loopwire::gateway {
namespace {

// Bounds and defaults are the ones gateway_config.cpp enforces and gateway_config.hpp sets; a
// test parses every key's example and the printed configuration, so a drift is a failure.
constexpr std::array tables{
    ConfigTable{"gateway", "[gateway]", "The gateway itself. Optional."},
    ConfigTable{"lines", "[[lines]]",
                "One table per line the gateway owns: a serial port, a Modbus TCP device, RTU through a device server, "
                "or a simulated line. At least one."},
    ConfigTable{"lines.devices", "[[lines.devices]]",
                "One table per device on the line above it; its values are polled and served on every front."},
    ConfigTable{"lines.devices.points", "[[lines.devices.points]]",
                "A device loopwire has no profile for (a power meter, a drive) is described by its points instead of "
                "`device`: one table per value, and `unit = N` in the device's table. They are served as a profile's "
                "parameters are; `loopwire profile from-points FILE DEVICE` prints them as a profile file.",
                true},
    ConfigTable{"modbus_tcp", "[modbus_tcp]",
                "The Modbus TCP front: clients reach every device through it by its unit id. Absent: on, at "
                "127.0.0.1:1502, with these defaults."},
    ConfigTable{"log", "[log]", "What the gateway logs. Absent: these defaults."},
    ConfigTable{"mqtt", "[mqtt]",
                "Publish every polled value to an MQTT broker and take writes from it. Absent: no MQTT."},
    ConfigTable{"sparkplug", "[sparkplug]",
                "Join a Sparkplug B (Eclipse Sparkplug 3.0) SCADA as an edge node: births, data, deaths and commands "
                "in protobuf on spBv1.0/GROUP/... Beside [mqtt] or instead of it. Absent: no Sparkplug."},
    ConfigTable{"history", "[history]",
                "Record every change of a polled value, and a heartbeat of each, in an SQLite file the HTTP API "
                "charts from, and optionally forward it to a PostgreSQL historian. Absent: no history."},
    ConfigTable{"http", "[http]", "The HTTP API and the live dashboard. Absent: no HTTP."},
    ConfigTable{"opcua", "[opcua]",
                "The OPC UA front: every polled parameter a variable ns=1;s=DEVICE.PARAMETER under "
                "Objects/GATEWAY/LINE/DEVICE. Absent: no OPC UA."},
    ConfigTable{"alarms", "[alarms]",
                "Alarms in the states of ISA-18.2 (normal, active-unacknowledged, active-acknowledged, "
                "returned-unacknowledged, shelved, out-of-service). Every device has its communication alarms "
                "(DEVICE.silent, DEVICE.line_down, DEVICE.wrong_device) without any table; with [history] their "
                "journal is kept in its file and the states survive a restart."},
    ConfigTable{"alarms.limits", "[[alarms.limits]]",
                "One table per limit alarm on a polled number of a device; none: only the communication alarms."},
};

constexpr std::array keys{
    ConfigKey{"gateway", "name", "string", "", "letters, digits, '-' and '_'",
              "The gateway's name: the default MQTT prefix is loopwire/NAME, and discovery ids begin with it.",
              "\"plant1\""},

    ConfigKey{"lines", "name", "string", "", "letters, digits, '-' and '_'; unique",
              "The line's name in logs, metrics and the HTTP API.", "\"furnace-line\""},
    ConfigKey{"lines", "link", "string", "", "a link URL",
              "Where the line is: \"rtu:/dev/ttyUSB0?baud=19200&parity=even\" (also ascii: and linking:), "
              "\"tcp://192.0.2.7:502\", \"rtu+tcp://serial-server:4001\", or \"rtu:virtual?baud=19200\" for a line "
              "simulated inside the gateway. One serial port is one line.",
              "\"rtu:virtual?baud=19200\""},
    ConfigKey{"lines", "timeout", "duration", "\"1s\"", "at least 1ms",
              "How long a reply is waited for.", "\"1s\""},
    ConfigKey{"lines", "retries", "integer", "0", "0..10", "How often a request that got no reply is sent again.", "0"},
    ConfigKey{"lines", "late_reply_window", "duration", "the line's timeout", "1ms..1min",
              "After a request that got no usable reply, the next waits until the line has been quiet this long, so a "
              "late reply is never taken for another request's.",
              "\"1s\"", true},
    ConfigKey{"lines", "max_in_flight", "integer", "1", "1..64; more than 1 only on a tcp:// line",
              "Requests on the wire at once; a Modbus TCP device's replies are paired with requests by transaction id. "
              "Set it to what the device takes at once.",
              "1"},
    ConfigKey{"lines", "rs485", "boolean or \"auto\"", "false", "a serial line only",
              "Kernel RS-485 direction control (TIOCSRS485): the driver raises RTS while a frame is sent. true: a port "
              "whose driver lacks it does not open; \"auto\": such a port runs without it, said in the log when it opens. "
              "Overrides the link URL's rs485.",
              "\"auto\"", true},
    ConfigKey{"lines", "rs485_delay_before", "duration", "0", "1ms..1s, whole milliseconds; a serial line only",
              "With rs485: RTS is raised this long before the first bit of a frame.", "\"1ms\"", true},
    ConfigKey{"lines", "rs485_delay_after", "duration", "0", "1ms..1s, whole milliseconds; a serial line only",
              "With rs485: RTS is held this long after the last bit of a frame.", "\"1ms\"", true},
    ConfigKey{"lines", "guard", "string", "3.5 characters", "\"Nc\" up to 1000c, or a duration up to 1s; a serial line only",
              "Silence kept on the line before each request, counted from the last byte sent or received: in "
              "characters at the line's speed (\"3.5c\") or a time (\"5ms\"). Never less than the 3.5 characters RTU "
              "needs; more for devices slow to turn around.",
              "\"5ms\"", true},
    ConfigKey{"lines", "speed", "number", "1.0", "0.001..100000; a simulated line only",
              "Process seconds per real second of the simulated devices, as `loopwire simulate --speed`.", "1.0"},
    ConfigKey{"lines", "seed", "integer", "1", "0..4294967295; a simulated line only",
              "Seed of the simulated measurement noise, as `loopwire simulate --seed`.", "1"},

    ConfigKey{"lines.devices", "name", "string", "", "letters, digits, '-' and '_'; unique in the file",
              "The device's name in MQTT topics, URLs, metrics and logs.", "\"oven\""},
    ConfigKey{"lines.devices", "device", "string", "", "PROFILE@UNIT, the unit given; unit unique on the line",
              "The device's profile and unit address, as `loopwire read --device` takes it (`loopwire devices` lists "
              "the profiles and the protocols each speaks, one of which must be the line's). A device without a profile "
              "gives `unit` and [[lines.devices.points]] instead.",
              "\"tc10@3\""},
    ConfigKey{"lines.devices", "poll", "duration", "\"1s\"", "at least 1ms", "How often its parameters are polled.",
              "\"1s\""},
    ConfigKey{"lines.devices", "parameters", "list of strings", "the profile's watch list",
              "readable parameters of the profile, each named once",
              "The parameters polled, by name, alias or mnemonic as `loopwire read` takes them.",
              "[\"measured_value\", \"set_point\"]", true},
    ConfigKey{"lines.devices", "identify", "boolean", "true", "",
              "Whether its first poll, and the first after every outage, reads the profile's identification words "
              "and shows the device wrong-device, with none of its values, when the unit answers as another device.",
              "true", true},
    ConfigKey{"lines.devices", "tcp_unit", "integer", "the device's unit", "1..247; unique in the file",
              "The unit id Modbus TCP clients reach the device by (needed for units above 247).", "3", true},

    ConfigKey{"lines.devices", "unit", "integer", "none: `device` gives it", "1..247; unique on the line",
              "With [[lines.devices.points]] instead of `device`: the device's Modbus address.", "1", true},

    ConfigKey{"lines.devices.points", "name", "string", "", "lower-case letters, digits and '_'; unique in the device",
              "The point's name in the API, MQTT topics and history.", "\"energy_total\""},
    ConfigKey{"lines.devices.points", "table", "string", "the reference's", "holding, input, coil or discrete",
              "The Modbus table the point is in; may be left out when `address` is a reference.", "\"holding\""},
    ConfigKey{"lines.devices.points", "address", "integer or string", "", "0..65535, or a 4xxxx/3xxxx/0xxxx/1xxxx reference",
              "The wire address counted from 0, or a reference as manuals print them, counted from 1 (\"40001\" is "
              "holding register 0).", "12"},
    ConfigKey{"lines.devices.points", "type", "string", "bool for a coil or discrete input", "int16, uint16 or bits",
              "How the register holds the value: signed, unsigned, or 16 named bits (bit0..bit15).", "\"uint16\""},
    ConfigKey{"lines.devices.points", "decimals", "integer", "0", "0..4",
              "The value is the register divided by 10^decimals.", "1"},
    ConfigKey{"lines.devices.points", "scale", "factor", "1", "1, 0.1, 0.01, 0.001 or 0.0001",
              "The same as decimals, written as a factor (0.1 is decimals = 1).", "0.1"},
    ConfigKey{"lines.devices.points", "unit", "string", "none", "", "The value's unit.", "\"kWh\""},
    ConfigKey{"lines.devices.points", "min", "number in the point's unit", "none", "at most max", "The least value a write may set.", "0"},
    ConfigKey{"lines.devices.points", "max", "number in the point's unit", "none", "at least min", "The largest value a write may set.", "100"},
    ConfigKey{"lines.devices.points", "writable", "boolean", "false", "holding and coil points only",
              "Whether the fronts may write the point.", "false"},
    ConfigKey{"lines.devices.points", "poll", "boolean", "polled", "false only",
              "false: the point is not polled (still written and read on demand).", "false"},

    ConfigKey{"modbus_tcp", "enabled", "boolean", "true", "", "Whether the Modbus TCP front is served.", "true"},
    ConfigKey{"modbus_tcp", "listen", "string", "\"127.0.0.1:1502\"", "HOST:PORT or [IPV6]:PORT; port 0 takes any free one",
              "The address the front listens on.", "\"127.0.0.1:1502\""},
    ConfigKey{"modbus_tcp", "writes", "boolean", "true", "",
              "Whether clients may write; false answers anything but a read with exception 01h.", "true"},
    ConfigKey{"modbus_tcp", "max_age", "duration", "off", "at least 1ms",
              "A read (function codes 1-4) repeated within this long is answered from the last identical one without "
              "taking the line; a write through the device empties its cache.",
              "\"250ms\"", true},
    ConfigKey{"modbus_tcp", "max_connections", "integer", "64", "1..10000",
              "Clients connected at once; a newcomer past it is admitted by closing the idlest connection.", "64"},
    ConfigKey{"modbus_tcp", "idle_timeout", "duration", "\"60s\"", "1s..24h, or \"off\"",
              "A connection that has sent nothing and waited for nothing this long is closed.", "\"60s\""},
    ConfigKey{"modbus_tcp", "allow", "list of strings", "[]: every address", "IPv4 or IPv6 addresses and CIDR networks",
              "The client addresses served; a client from any other is closed at once and counted.",
              "[\"10.1.0.0/16\", \"127.0.0.1\"]", true},
    ConfigKey{"modbus_tcp", "write_allow", "list of strings", "[]: every address", "IPv4 or IPv6 addresses and CIDR networks",
              "The client addresses whose writes are passed on; a write from any other is answered with exception 01h.",
              "[\"10.1.5.0/24\"]", true},

    ConfigKey{"log", "level", "string", "\"info\"", "\"debug\", \"info\", \"warning\" or \"error\"",
              "The least important events logged.", "\"info\""},
    ConfigKey{"log", "statistics", "duration", "\"60s\"", "at least 1s, or \"off\"",
              "How often each line's figures are logged (\"off\": only when the gateway stops).", "\"60s\""},

    ConfigKey{"mqtt", "broker", "string", "", "mqtt://HOST[:PORT] or mqtts://HOST[:PORT] (TLS)",
              "The broker; the port defaults to 1883, over TLS to 8883.", "\"mqtt://127.0.0.1:1883\""},
    ConfigKey{"mqtt", "prefix", "string", "loopwire/ and the gateway's name", "topic levels without '+', '#' or spaces, "
              "none empty, not starting with '$'",
              "The topics' first levels: values are at PREFIX/DEVICE/PARAMETER.", "\"loopwire/plant1\""},
    ConfigKey{"mqtt", "writes", "boolean", "false", "",
              "Whether QoS 1 messages on PREFIX/DEVICE/PARAMETER/set are written to the device.", "false"},
    ConfigKey{"mqtt", "client_id", "string", "loopwire- and the prefix", "1..256 characters",
              "The MQTT client id; the broker keeps the gateway's session under it.", "\"loopwire-plant1\"", true},
    ConfigKey{"mqtt", "ca_file", "file", "the system's certificate store", "a regular file, PEM; mqtts:// only",
              "The CA certificate the broker's certificate is checked against.", "\"ca.crt\"", true},
    ConfigKey{"mqtt", "cert_file", "file", "none", "a regular file, PEM; mqtts:// only; with key_file",
              "The gateway's client certificate, for brokers that ask for one.", "\"gateway.crt\"", true},
    ConfigKey{"mqtt", "key_file", "file", "none", "a regular file, PEM; mqtts:// only; with cert_file",
              "The private key of cert_file.", "\"gateway.key\"", true},
    ConfigKey{"mqtt", "username", "string", "none", "", "The user name sent to the broker.", "\"gateway\"", true},
    ConfigKey{"mqtt", "password_file", "file", "none", "a regular file not readable by every user; needs username",
              "A file whose first line is the broker password.", "\"mqtt.password\"", true},
    ConfigKey{"mqtt", "republish", "duration", "\"5m\"", "at least 100ms, or \"off\"",
              "Every value is published when it changes and again at least this often (\"off\": on changes only).",
              "\"5m\""},
    ConfigKey{"mqtt", "discovery", "string", "\"none\"", "\"homeassistant\" or \"none\"",
              "Publish Home Assistant discovery documents for every polled parameter.", "\"none\""},
    ConfigKey{"mqtt", "discovery_prefix", "string", "\"homeassistant\"", "topic levels without '+', '#' or spaces",
              "The discovery documents' first topic level.", "\"homeassistant\""},
    ConfigKey{"mqtt", "max_payload", "integer", "1024", "16..65536 (bytes)",
              "A .../set payload longer than this is refused unread.", "1024"},

    ConfigKey{"sparkplug", "broker", "string", "", "mqtt://HOST[:PORT] or mqtts://HOST[:PORT] (TLS)",
              "The broker the SCADA host application uses; TLS and credentials as in [mqtt].", "\"mqtt://127.0.0.1:1883\""},
    ConfigKey{"sparkplug", "group_id", "string", "", "1..64 letters, digits, '.', '-' or '_'",
              "The Sparkplug group: topics are spBv1.0/GROUP/...", "\"plant1\""},
    ConfigKey{"sparkplug", "edge_node_id", "string", "the gateway's name, else \"loopwire\"",
              "1..64 letters, digits, '.', '-' or '_'", "The edge node's id; each configured device is a Sparkplug device of it.",
              "\"cabinet1\"", true},
    ConfigKey{"sparkplug", "primary_host", "string", "none", "1..64 letters, digits, '.', '-' or '_'",
              "A host application id: births wait until spBv1.0/STATE/HOST says it is online, and the node "
              "disconnects and waits again when it goes offline.",
              "\"scada\"", true},
    ConfigKey{"sparkplug", "state_file", "file", "none: bdSeq counts from 0 at each start", "a regular file or none yet",
              "Where the node keeps the bdSeq of its next session, written at each connect, so that a host sees it count "
              "on across restarts (Sparkplug 3.0); relative to this file's folder.",
              "\"/var/lib/loopwire/sparkplug.state\"", true},
    ConfigKey{"sparkplug", "store_and_forward", "duration", "\"off\"", "1s..24h, or \"off\"",
              "While the broker cannot be reached (or the primary host is offline), the data the node would have sent "
              "is kept this long (at most 100000 values, the oldest dropped first) and sent after the next births "
              "with is_historical and its own timestamps.",
              "\"10m\"", true},
    ConfigKey{"sparkplug", "writes", "boolean", "false", "",
              "Whether DCMD metrics are written to the device (checked as `loopwire write` checks them).", "false"},
    ConfigKey{"sparkplug", "client_id", "string", "loopwire-sparkplug-GROUP-EDGE", "1..256 characters",
              "The MQTT client id.", "\"cabinet1-sparkplug\"", true},
    ConfigKey{"sparkplug", "ca_file", "file", "the system's certificate store", "a regular file, PEM; mqtts:// only",
              "The CA certificate the broker's certificate is checked against.", "\"ca.crt\"", true},
    ConfigKey{"sparkplug", "cert_file", "file", "none", "a regular file, PEM; mqtts:// only; with key_file",
              "The gateway's client certificate, for brokers that ask for one.", "\"gateway.crt\"", true},
    ConfigKey{"sparkplug", "key_file", "file", "none", "a regular file, PEM; mqtts:// only; with cert_file",
              "The private key of cert_file.", "\"gateway.key\"", true},
    ConfigKey{"sparkplug", "username", "string", "none", "", "The user name sent to the broker.", "\"gateway\"", true},
    ConfigKey{"sparkplug", "password_file", "file", "none", "a regular file not readable by every user; needs username",
              "A file whose first line is the broker password.", "\"mqtt.password\"", true},

    ConfigKey{"history", "database", "file", "", "a regular file or none yet, in a folder the gateway can write",
              "The SQLite file (WAL mode), created when absent; relative to the configuration file's folder.",
              "\"plant.db\""},
    ConfigKey{"history", "keep", "period", "\"90d\"", "at least 1m",
              "Rows older than this are deleted as the gateway runs (with forward_to: also rows not yet forwarded, counted in "
              "the log), and so are the historian's day partitions.", "\"90d\""},
    ConfigKey{"history", "heartbeat", "duration", "\"60s\"", "at least 1s",
              "Every current value is written again at least this often, so a value that holds still is a line, not a gap.",
              "\"60s\""},
    // `database` stays the local SQLite file whether or not the history is forwarded: it is the
    // gateway's own history and the buffer rows wait in while PostgreSQL is away; forward_to
    // names the shared historian (gateway/history_forwarder.hpp).
    ConfigKey{"history", "forward_to", "string", "none",
              "a PostgreSQL connection string: postgresql://USER@HOST:PORT/DATABASE, postgresql:///DATABASE?host=SOCKET_DIR, "
              "or \"host=... dbname=...\"; needs [gateway] name",
              "Forward the history to this PostgreSQL database, shared by many gateways: rows go to the SQLite file first "
              "and are shipped in order, exactly once, retried while the server is away. TLS by the string's sslmode.",
              "\"postgresql://gateway@historian:5432/plant\"", true},
    ConfigKey{"history", "password_file", "file", "the string's password, else PGPASSFILE's",
              "a regular file not readable by every user; needs forward_to",
              "A file whose first line is the PostgreSQL password.", "\"historian.password\"", true},

    ConfigKey{"http", "listen", "string", "\"127.0.0.1:8080\"", "HOST:PORT or [IPV6]:PORT; port 0 takes any free one",
              "The address the API and dashboard are served on; off loopback every request needs the token.",
              "\"127.0.0.1:8080\""},
    ConfigKey{"http", "token_file", "file", "none: writes are refused", "a regular file readable by the gateway's user alone",
              "A file whose first line is the bearer token writes need; relative to the configuration file's folder.",
              "\"/etc/loopwire/token\"", true},
    ConfigKey{"http", "users_file", "file", "none: the token alone", "a regular file not readable by every user",
              "Users who log in to the API and dashboard, one NAME:ROLE:HASH line each (loopwire passwd writes them); "
              "roles viewer, operator, admin. A reload (SIGHUP) reads it again.", "\"/etc/loopwire/users\"", true},
    ConfigKey{"http", "open_reads", "string", "\"loopback\"", "loopback, none or all; without users_file it has no effect",
              "Who reads without logging in when there is a users_file: clients on loopback, nobody, or everyone.",
              "\"loopback\""},
    ConfigKey{"http", "session_timeout", "duration", "\"8h\"", "1min..24h",
              "A login's session not used this long ends.", "\"8h\""},
    ConfigKey{"http", "certificate", "file", "none: plain HTTP", "a regular file, PEM; needs private_key",
              "The server's certificate (its chain after it): the API and dashboard are served over HTTPS alone (TLS 1.2 "
              "and 1.3). A reload (SIGHUP) reads it again.", "\"/etc/loopwire/https.crt\"", true},
    ConfigKey{"http", "private_key", "file", "none", "a regular file not readable by every user, PEM; needs certificate",
              "The certificate's private key, without a passphrase.", "\"/etc/loopwire/https.key\"", true},
    ConfigKey{"http", "read_timeout", "duration", "\"10s\"", "100ms..10min",
              "A client that has not sent its whole request this long after it began is closed.", "\"10s\""},
    ConfigKey{"http", "send_timeout", "duration", "\"10s\"", "100ms..10min",
              "An event stream whose client has taken nothing of what waits for it this long is closed.", "\"10s\""},
    ConfigKey{"http", "header_timeout", "duration", "\"5s\"", "100ms..10min",
              "A client that has not sent a request's header this long after it connected (or after the response "
              "before) is closed; read_timeout, if shorter, counts instead.", "\"5s\""},
    ConfigKey{"http", "max_connections", "integer", "64", "1..10000",
              "Connections open at once; at the limit a newcomer takes the place of the one that has waited longest "
              "for a request, else it is answered 503.", "64"},
    ConfigKey{"http", "max_connections_per_client", "integer", "8", "1..10000",
              "Connections one client address may hold at once; more are answered 429.", "8"},
    ConfigKey{"http", "max_event_streams", "integer", "half of max_connections", "1..10000, fewer than max_connections",
              "Event streams (/api/events, one per open dashboard) open at once; more are answered 503, so that "
              "requests always find a connection.", "32"},
    ConfigKey{"http", "max_event_streams_per_client", "integer", "half of max_connections_per_client",
              "1..10000, fewer than max_connections_per_client",
              "Event streams one client address may hold at once; more are answered 429.", "4"},
    ConfigKey{"http", "hosts", "list of strings", "[]", "host names or addresses",
              "Host header names answered besides the listen address, localhost, 127.0.0.1 and [::1]; others get 421.",
              "[]"},
    ConfigKey{"http", "allow", "list of strings", "[]: every address", "IPv4 or IPv6 addresses and CIDR networks",
              "The client addresses served; a client from any other is closed at once and counted.",
              "[\"10.1.0.0/16\", \"127.0.0.1\"]", true},

    ConfigKey{"opcua", "listen", "string", "\"opc.tcp://127.0.0.1:4840\"",
              "opc.tcp://HOST:PORT or opc.tcp://[IPV6]:PORT; port 0 takes any free one",
              "The endpoint OPC UA clients connect to.", "\"opc.tcp://127.0.0.1:4840\""},
    ConfigKey{"opcua", "writes", "boolean", "false", "",
              "Whether clients may write variables; false answers every write Bad_NotWritable.", "false"},
    ConfigKey{"opcua", "anonymous", "boolean", "true", "",
              "Whether anonymous sessions are taken; the endpoint offers security policy None only.", "true"},
    ConfigKey{"opcua", "application_name", "string", "\"loopwire GATEWAY\"", "",
              "The server's application name, as clients list it.", "\"loopwire plant1\"", true},
    ConfigKey{"opcua", "application_uri", "string", "\"urn:loopwire:GATEWAY\"", "",
              "The server's application URI.", "\"urn:loopwire:plant1\"", true},
    ConfigKey{"opcua", "max_sessions", "integer", "100", "1..10000", "Sessions open at once.", "100"},
    ConfigKey{"opcua", "max_subscriptions", "integer", "1000", "1..100000", "Subscriptions over every session.", "1000"},
    ConfigKey{"opcua", "max_monitored_items", "integer", "100000", "1..1000000",
              "Monitored items over every subscription.", "100000"},
    ConfigKey{"alarms.limits", "device", "string", "", "a device of [[lines.devices]]", "The device whose value is watched.",
              "\"oven\""},
    ConfigKey{"alarms.limits", "parameter", "string", "", "a polled parameter of the device that is a number",
              "The value compared with the limit (PV), by name, alias or mnemonic.", "\"measured_value\""},
    ConfigKey{"alarms.limits", "kind", "string", "", "high, high_high, low, low_low or deviation",
              "Active while the value is above (high, high_high) or below (low, low_low) `limit`, or while "
              "|PV - SP| is beyond `limit` (deviation, with `setpoint`).",
              "\"high\""},
    ConfigKey{"alarms.limits", "limit", "number in the parameter's unit", "", "",
              "The limit, in the parameter's unit; for deviation the largest |PV - SP| allowed.", "250"},
    ConfigKey{"alarms.limits", "setpoint", "string", "none", "a polled number of the device; read by deviation alone",
              "The parameter PV is compared with (SP).", "\"set_point\"", true},
    ConfigKey{"alarms.limits", "deadband", "number in the parameter's unit", "0", "0 or more",
              "How far back past the limit the value must go for the alarm to clear: a value wavering around the "
              "limit raises one alarm, not one per poll.",
              "2.0"},
    ConfigKey{"alarms.limits", "on_delay", "duration", "none", "1ms..24h",
              "How long the value must stay beyond the limit before the alarm is raised.", "\"5s\""},
    ConfigKey{"alarms.limits", "off_delay", "duration", "none", "1ms..24h",
              "How long the value must stay back before the alarm clears.", "\"2s\""},
    ConfigKey{"alarms.limits", "severity", "string", "\"medium\"", "low, medium, high or critical",
              "The alarm's priority, in the API, the journal and the metrics.", "\"high\""},
    ConfigKey{"alarms.limits", "message", "string", "made from parameter, kind and limit", "",
              "What the alarm says to the operator.", "\"oven too hot\""},
    ConfigKey{"alarms.limits", "name", "string", "PARAMETER_KIND", "letters, digits, '-' and '_'; unique on the device",
              "The alarm's name: the API names it DEVICE.NAME.", "\"too_hot\"", true},
};

constexpr double unbounded = std::numeric_limits<double>::infinity();

constexpr std::array ranges{
    ConfigRange{"lines", "retries", 0, 10},
    // Modbus TCP servers take as many transactions at once as they were built for
    // (NumberMaxOfServerTransaction, MODBUS Messaging on TCP/IP Implementation Guide V1.0b); 1
    // is what every device takes, and past a few dozen a gateway's queue only moves into the
    // device's.
    ConfigRange{"lines", "max_in_flight", 1, 64},
    ConfigRange{"lines", "speed", 0.001, 100000},
    ConfigRange{"lines", "seed", 0, 4294967295.0},
    ConfigRange{"lines.devices", "tcp_unit", 1, 247},  // Modbus unit ids end at 247
    ConfigRange{"lines.devices", "unit", 1, 247},
    ConfigRange{"lines.devices.points", "decimals", 0, 4},
    ConfigRange{"modbus_tcp", "max_connections", 1, 10000},
    ConfigRange{"mqtt", "max_payload", 16, 65536},
    ConfigRange{"http", "max_connections", 1, 10000},
    ConfigRange{"http", "max_connections_per_client", 1, 10000},
    ConfigRange{"http", "max_event_streams", 1, 10000},
    ConfigRange{"http", "max_event_streams_per_client", 1, 10000},
    ConfigRange{"opcua", "max_sessions", 1, 10000},
    ConfigRange{"opcua", "max_subscriptions", 1, 100000},
    ConfigRange{"opcua", "max_monitored_items", 1, 1000000},
    // Durations, in milliseconds.
    ConfigRange{"lines", "timeout", 1, unbounded},
    // A late reply comes at most a few timeouts late; a longer window would only stall the line.
    ConfigRange{"lines", "late_reply_window", 1, 60'000},
    // What struct serial_rs485 carries; drivers cap it lower.
    ConfigRange{"lines", "rs485_delay_before", 1, 1'000},
    ConfigRange{"lines", "rs485_delay_after", 1, 1'000},
    ConfigRange{"lines.devices", "poll", 1, unbounded},
    ConfigRange{"modbus_tcp", "max_age", 1, unbounded},
    ConfigRange{"modbus_tcp", "idle_timeout", 1'000, 86'400'000},
    // Closer together, the figures would bury everything else in the log.
    ConfigRange{"log", "statistics", 1'000, unbounded},
    ConfigRange{"alarms.limits", "on_delay", 1, 86'400'000},
    ConfigRange{"alarms.limits", "off_delay", 1, 86'400'000},
    ConfigRange{"mqtt", "republish", 100, unbounded},
    ConfigRange{"history", "heartbeat", 1'000, unbounded},
    // The values are kept in memory (at most 100000 of them): a day covers an outage someone
    // attends to; a longer one is for a historian that reads the [history] database.
    ConfigRange{"sparkplug", "store_and_forward", 1'000, 86'400'000},
    ConfigRange{"http", "read_timeout", 100, 600'000},
    ConfigRange{"http", "header_timeout", 100, 600'000},
    ConfigRange{"http", "send_timeout", 100, 600'000},
    ConfigRange{"http", "session_timeout", 60'000, 86'400'000},
};

// A table's last level: "devices" of "lines.devices".
std::string_view last_level(std::string_view name) { return name.substr(name.rfind('.') + 1); }

std::string_view parent_of(std::string_view name) {
    const auto dot = name.rfind('.');
    return dot == std::string_view::npos ? std::string_view() : name.substr(0, dot);
}

// `text` as comment lines of at most 100 characters, broken between words.
void print_comment(std::ostringstream& out, std::string_view text) {
    constexpr std::size_t width = 100 - 2;
    while (!text.empty()) {
        std::size_t end = text.size();
        if (end > width) {
            end = text.rfind(' ', width);
            if (end == std::string_view::npos || end == 0) end = width;
        }
        out << "# " << text.substr(0, end) << '\n';
        text.remove_prefix(end);
        while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
    }
}

void print_key(std::ostringstream& out, const ConfigKey& key, bool commented) {
    print_comment(out, key.meaning);
    std::string facts = fmt::format("{}", key.type);
    if (!key.bounds.empty()) facts += fmt::format(", {}", key.bounds);
    facts += key.required() ? "; required" : fmt::format("; default {}", key.default_value);
    print_comment(out, "(" + facts + ")");
    out << fmt::format("{}{} = {}\n", commented || key.example_commented ? "# " : "", key.key, key.example);
}

}  // namespace

std::span<const ConfigTable> config_tables() { return tables; }
std::span<const ConfigKey> config_keys() { return keys; }

std::span<const ConfigRange> config_ranges() { return ranges; }

const ConfigKey& config_key(std::string_view table, std::string_view key) {
    for (const ConfigKey& described : keys) {
        if (described.table == table && described.key == key) return described;
    }
    throw std::logic_error(fmt::format("the configuration schema does not describe {}.{}", table, key));
}

const ConfigRange& config_range(std::string_view table, std::string_view key) {
    for (const ConfigRange& range : ranges) {
        if (range.table == table && range.key == key) return range;
    }
    throw std::logic_error(fmt::format("the configuration schema gives {}.{} no range", table, key));
}

std::vector<std::string_view> config_keys_of(std::string_view table) {
    std::vector<std::string_view> names;
    for (const ConfigKey& key : keys) {
        if (key.table == table) names.push_back(key.key);
    }
    for (const ConfigTable& child : tables) {
        if (parent_of(child.name) == table) names.push_back(last_level(child.name));
    }
    return names;
}

std::string commented_example_config() {
    std::ostringstream out;
    out << "# A loopwire gateway configuration with every key: its meaning, the values it takes and its default\n"
           "# (loopwire-gateway.toml(5)). Keys commented out are not set. As printed it runs one simulated line;\n"
           "# name your own lines and devices, then check the file:\n"
           "#   loopwire gateway --config gateway.toml --check\n";
    for (const ConfigTable& table : tables) {
        // A table that cannot stand beside the example's other keys is shown commented out.
        out << fmt::format("\n{}{}\n", table.example_commented ? "# " : "", table.header);
        print_comment(out, table.meaning);
        for (const ConfigKey& key : keys) {
            if (key.table == table.name) print_key(out, key, table.example_commented);
        }
    }
    return out.str();
}

}  // namespace loopwire::gateway
