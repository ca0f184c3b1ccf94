// The gateway configuration (gateway/gateway_config.hpp): what a plant file parses to, the
// errors a wrong one gives (file:line, key path, what is expected), and the plan
// `loopwire gateway --check` prints, load figures checked against frame sizes worked out here.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <stdlib.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "gateway/device_points.hpp"
#include "gateway/gateway_config.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::gateway {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

const device::ProfileRegistry& profiles() { return device::testing::builtin_registry(); }

Result<GatewayConfig> parse(const std::string& text) { return parse_gateway_config(text, "plant.toml", profiles()); }

// The error message of a configuration that must be refused ("" and a failure when it parses).
std::string error_of(const std::string& text) {
    auto config = parse(text);
    if (config) {
        ADD_FAILURE() << "parsed, but should have been refused:\n" << text;
        return {};
    }
    EXPECT_EQ(config.error().kind, ErrorKind::usage);
    return config.error().message;
}

// A plant's example; line numbers matter to the tests below.
const std::string example = R"toml([[lines]]
name = "furnace-line"
link = "rtu:/dev/ttyUSB0?baud=19200&parity=none"
timeout = "300ms"
retries = 1

[[lines.devices]]
name = "oven1"            # used in MQTT topics, URLs, logs
device = "tc10@3"         # profile@unit, or a profile file
poll = "1s"               # interval of the default parameter set
parameters = ["measured_value", "set_point"]   # optional; default: the profile's monitor set
tcp_unit = 13             # optional: unit id Modbus TCP clients use, default = the device's unit

[modbus_tcp]
listen = "127.0.0.1:1502" # loopback by default; another address only when written here
writes = true
enabled = true            # optional
)toml";

std::string tc10_line_for_simulation() {
    return "[[lines]]\nname = \"l1\"\nlink = \"rtu:/dev/ttyUSB0?baud=19200\"\n[[lines.devices]]\nname = \"oven1\"\n"
           "device = \"tc10@3\"\n";
}

// One line with one tc10 device, and `extra` appended to the device table (line 7 on).
std::string one_device(const std::string& extra) {
    return "[[lines]]\n"                   // 1
           "name = \"l1\"\n"               // 2
           "link = \"rtu:virtual\"\n"      // 3
           "\n"                            // 4
           "[[lines.devices]]\n"           // 5
           "name = \"oven1\"\n"            // 6
           + extra;                        // 7...
}

// --check catches what would only fail, or do something else, once the gateway runs.
TEST(GatewayConfig, AnEmptyOrRepeatingParameterListIsRefused) {
    EXPECT_EQ(error_of(one_device("device = \"tc10@3\"\nparameters = []\n")),
              "plant.toml:8: lines[0].devices[0].parameters: device oven1: an empty list polls nothing; name the parameters "
              "to poll, or leave the key out for the profile's watch list");
    EXPECT_EQ(error_of(one_device("device = \"tc10@3\"\nparameters = [\"PV\", \"set_point\", \"measured_value\"]\n")),
              "plant.toml:8: lines[0].devices[0].parameters[2]: device oven1: \"measured_value\" is measured_value, already "
              "named at lines[0].devices[0].parameters[0]; name each parameter once");
    EXPECT_TRUE(parse(one_device("device = \"tc10@3\"\nparameters = [\"PV\", \"SP\"]\n")));
}

TEST(GatewayConfig, DevicesAreIdentifiedUnlessToldNot) {
    auto checked = parse(one_device("device = \"tc10@3\"\n"));
    ASSERT_TRUE(checked) << checked.error().message;
    EXPECT_TRUE(checked->lines[0].devices[0].identify);
    auto trusted = parse(one_device("device = \"tc10@3\"\nidentify = false\n"));
    ASSERT_TRUE(trusted) << trusted.error().message;
    EXPECT_FALSE(trusted->lines[0].devices[0].identify);
    EXPECT_EQ(error_of(one_device("device = \"tc10@3\"\nidentify = \"no\"\n")),
              "plant.toml:8: lines[0].devices[0].identify: expected true or false");
}

TEST(GatewayConfig, AUnitPastModbusTcpsRangeNeedsATcpUnit) {
    EXPECT_EQ(error_of(one_device("device = \"tc10@248\"\n")),
              "plant.toml:7: lines[0].devices[0].device: device oven1: unit 248 cannot be a Modbus TCP unit (1..247); give "
              "it one with tcp_unit = N");
    auto config = parse(one_device("device = \"tc10@248\"\ntcp_unit = 48\n"));
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->lines[0].devices[0].tcp_unit, 48);
    EXPECT_EQ(config->lines[0].devices[0].address.unit, 248);
}

TEST(GatewayConfig, TwoLinesOnOneSerialPortAreRefused) {
    const std::string text = "[[lines]]\nname = \"a\"\nlink = \"rtu:/dev/ttyUSB0?baud=19200\"\n\n"
                             "[[lines]]\nname = \"b\"\nlink = \"ascii:/dev/ttyUSB0?baud=9600\"\n";
    EXPECT_EQ(error_of(text), "plant.toml:7: lines[1].link: /dev/ttyUSB0 is already the port of line a (lines[0], line 1); "
                              "one port is one line: put the devices of both in one [[lines]] table");
    EXPECT_TRUE(parse("[[lines]]\nname = \"a\"\nlink = \"rtu:virtual\"\n\n[[lines]]\nname = \"b\"\nlink = \"rtu:virtual\"\n"));
}

TEST(GatewayConfig, AFullExampleParsesToItsValues) {
    auto config = parse(example);
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->source, "plant.toml");
    ASSERT_EQ(config->lines.size(), 1u);
    const LineConfig& line = config->lines[0];
    EXPECT_EQ(line.name, "furnace-line");
    EXPECT_EQ(line.link.framing, transport::Framing::rtu);
    EXPECT_EQ(line.link.path, "/dev/ttyUSB0");
    EXPECT_EQ(line.link.serial.baud, 19200u);
    EXPECT_EQ(line.link.serial.parity, transport::Parity::none);
    EXPECT_EQ(line.timeout, std::chrono::milliseconds(300));
    EXPECT_EQ(line.retries, 1u);
    ASSERT_EQ(line.devices.size(), 1u);
    const DeviceConfig& oven = line.devices[0];
    EXPECT_EQ(oven.name, "oven1");
    ASSERT_NE(oven.address.profile, nullptr);
    EXPECT_EQ(oven.address.profile->id, "tc10");
    EXPECT_EQ(oven.address.unit, 3);
    EXPECT_EQ(oven.tcp_unit, 13);
    EXPECT_EQ(oven.poll, std::chrono::milliseconds(1000));
    EXPECT_EQ(oven.parameters, (std::vector<std::string>{"measured_value", "set_point"}));
    EXPECT_TRUE(config->modbus_tcp.enabled);
    EXPECT_TRUE(config->modbus_tcp.writes);
    EXPECT_EQ(config->modbus_tcp.host, "127.0.0.1");
    EXPECT_EQ(config->modbus_tcp.port, 1502);
}

TEST(GatewayConfig, DefaultsApplyToWhatIsLeftOut) {
    auto config = parse(one_device("device = \"ac20@5\"\n"));
    ASSERT_TRUE(config) << config.error().message;
    const LineConfig& line = config->lines[0];
    EXPECT_EQ(line.timeout, std::chrono::milliseconds(1000));
    EXPECT_EQ(line.retries, 0u);
    EXPECT_EQ(line.late_reply_window, std::nullopt);  // as long as the timeout
    EXPECT_EQ(line.devices[0].tcp_unit, 5);  // the device's own unit
    EXPECT_EQ(line.devices[0].poll, std::chrono::milliseconds(1000));
    EXPECT_TRUE(line.devices[0].parameters.empty());  // the default watch list
    EXPECT_TRUE(config->modbus_tcp.enabled);
    EXPECT_TRUE(config->modbus_tcp.writes);
    EXPECT_EQ(config->modbus_tcp.host, "127.0.0.1");  // loopback unless written otherwise
    EXPECT_EQ(config->modbus_tcp.port, 1502);
    EXPECT_EQ(config->modbus_tcp.max_connections, 64u);
    EXPECT_EQ(config->modbus_tcp.idle_timeout, std::chrono::seconds(60));
}

// SIGHUP (app/gateway_command.cpp): a file read again with nothing changed, or only the log
// level, keeps the running gateway; anything it runs on changed needs it opened again.
TEST(GatewayConfig, AReloadRestartsOnlyWhenSomethingServedChanged) {
    const std::string base = one_device("device = \"tc10@3\"\n") + "[http]\nlisten = \"127.0.0.1:0\"\n";
    auto running = parse(base + "[log]\nlevel = \"info\"\n");
    ASSERT_TRUE(running.ok()) << running.error().message;
    auto same = parse(base + "[log]\nlevel = \"info\"\n");
    auto louder = parse(base + "[log]\nlevel = \"debug\"\n");
    auto other_poll = parse(one_device("device = \"tc10@3\"\npoll = \"2s\"\n") + "[http]\nlisten = \"127.0.0.1:0\"\n");
    auto other_unit = parse(one_device("device = \"tc10@4\"\n") + "[http]\nlisten = \"127.0.0.1:0\"\n");
    auto no_http = parse(one_device("device = \"tc10@3\"\n"));
    auto other_stats = parse(base + "[log]\nstatistics = \"5s\"\n");
    for (const auto* config : {&same, &louder, &other_poll, &other_unit, &no_http, &other_stats}) {
        ASSERT_TRUE(config->ok()) << config->error().message;
    }
    EXPECT_FALSE(reload_needs_restart(*running, *same));
    EXPECT_FALSE(reload_needs_restart(*running, *louder));
    EXPECT_TRUE(reload_needs_restart(*running, *other_poll));
    EXPECT_TRUE(reload_needs_restart(*running, *other_unit));
    EXPECT_TRUE(reload_needs_restart(*running, *no_http));
    EXPECT_TRUE(reload_needs_restart(*running, *other_stats));
}

TEST(GatewayConfig, TheFrontsConnectionLimitsAreRead) {
    auto config = parse(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nmax_connections = 8\nidle_timeout = \"2m\"\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->modbus_tcp.max_connections, 8u);
    EXPECT_EQ(config->modbus_tcp.idle_timeout, std::chrono::minutes(2));
    auto off = parse(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nidle_timeout = \"off\"\n");
    ASSERT_TRUE(off) << off.error().message;
    EXPECT_EQ(off->modbus_tcp.idle_timeout.count(), 0);
}

TEST(GatewayConfig, BadConnectionLimitsSayWhatIsExpected) {
    const std::string tcp = one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\n";
    EXPECT_THAT(error_of(tcp + "max_connections = 0\n"),
                StartsWith("plant.toml:9: modbus_tcp.max_connections: 0 is out of range (expected an integer 1..10000)"));
    EXPECT_THAT(error_of(tcp + "max_connections = \"many\"\n"),
                StartsWith("plant.toml:9: modbus_tcp.max_connections: expected an integer 1..10000"));
    EXPECT_THAT(error_of(tcp + "idle_timeout = \"100ms\"\n"),
                StartsWith("plant.toml:9: modbus_tcp.idle_timeout: expected 1s..24h, or \"off\" (e.g. \"60s\""));
    EXPECT_THAT(error_of(tcp + "idle_timeout = \"forever\"\n"), StartsWith("plant.toml:9: modbus_tcp.idle_timeout: "));
}

TEST(GatewayConfig, ModbusTcpSettingsAreRead) {
    auto config = parse(one_device("device = \"tc10@3\"\n") +
                        "[modbus_tcp]\nlisten = \"0.0.0.0:502\"\nwrites = false\nenabled = false\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->modbus_tcp.host, "0.0.0.0");
    EXPECT_EQ(config->modbus_tcp.port, 502);
    EXPECT_FALSE(config->modbus_tcp.writes);
    EXPECT_FALSE(config->modbus_tcp.enabled);

    auto ipv6 = parse(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nlisten = \"[::1]:1502\"\n");
    ASSERT_TRUE(ipv6) << ipv6.error().message;
    EXPECT_EQ(ipv6->modbus_tcp.host, "::1");
    EXPECT_EQ(ipv6->modbus_tcp.port, 1502);
}

TEST(GatewayConfig, TheReadCacheIsOffUnlessAMaxAgeIsGiven) {
    auto off = parse(one_device("device = \"tc10@3\"\n"));
    ASSERT_TRUE(off) << off.error().message;
    EXPECT_EQ(off->modbus_tcp.max_age.count(), 0);

    auto on = parse(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nmax_age = \"500ms\"\n");
    ASSERT_TRUE(on) << on.error().message;
    EXPECT_EQ(on->modbus_tcp.max_age, std::chrono::milliseconds(500));
    auto seconds = parse(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nmax_age = \"1.5s\"\n");
    ASSERT_TRUE(seconds) << seconds.error().message;
    EXPECT_EQ(seconds->modbus_tcp.max_age, std::chrono::milliseconds(1500));
}

TEST(GatewayConfig, ABadMaxAgeNamesTheKeyAndTheForm) {
    const std::string word = error_of(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nmax_age = \"recent\"\n");
    EXPECT_THAT(word, StartsWith("plant.toml:9: modbus_tcp.max_age: 'recent' is not a duration: write it like 500ms"))
        << word;
    const std::string zero = error_of(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nmax_age = \"0ms\"\n");
    EXPECT_THAT(zero, StartsWith("plant.toml:9: modbus_tcp.max_age: '0ms' is too short: give at least 1ms")) << zero;
    const std::string number = error_of(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nmax_age = 500\n");
    EXPECT_THAT(number, StartsWith("plant.toml:9: modbus_tcp.max_age: expected a duration string")) << number;
}

TEST(GatewayConfig, ASyntaxErrorGivesLineColumnAndTheParsersWords) {
    const std::string message = error_of("[[lines]]\nname = \"a\"\nlink = = \"rtu:virtual\"\n");
    EXPECT_THAT(message, StartsWith("plant.toml:3:8: TOML syntax error: ")) << message;
    EXPECT_GT(message.size(), std::string("plant.toml:3:8: TOML syntax error: ").size()) << message;
}

TEST(GatewayConfig, AnUnknownKeyIsNamedWithTheAllowedOnes) {
    const std::string device = error_of(one_device("device = \"tc10@3\"\npol = \"1s\"\n"));
    EXPECT_EQ(device, "plant.toml:8: lines[0].devices[0].pol: unknown key (allowed here: name, device, poll, parameters, identify, tcp_unit, unit, points)");

    const std::string line = error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\ntimout = \"1s\"\n");
    EXPECT_EQ(line, "plant.toml:4: lines[0].timout: unknown key (allowed here: name, link, timeout, retries, late_reply_window, "
                    "max_in_flight, rs485, rs485_delay_before, "
                    "rs485_delay_after, guard, speed, seed, devices)");

    const std::string top = error_of(one_device("device = \"tc10@3\"\n") + "[modbus]\nlisten = \"127.0.0.1:1502\"\n");
    EXPECT_EQ(top, "plant.toml:8: modbus: unknown key (allowed here: gateway, lines, modbus_tcp, log, mqtt, sparkplug, history, http, "
                   "opcua, alarms)");

    const std::string tcp = error_of(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nwrite = false\n");
    EXPECT_EQ(tcp, "plant.toml:9: modbus_tcp.write: unknown key (allowed here: enabled, listen, writes, max_age, "
                   "max_connections, idle_timeout, allow, write_allow)");
}

TEST(GatewayConfig, TheLateReplyWindowIsReadAndBounded) {
    auto config = parse("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\nlate_reply_window = \"750ms\"\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->lines[0].late_reply_window, std::chrono::milliseconds(750));

    const std::string zero = error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\nlate_reply_window = \"0s\"\n");
    EXPECT_THAT(zero, StartsWith("plant.toml:4: lines[0].late_reply_window: expected 1ms..1min")) << zero;
    const std::string huge = error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\nlate_reply_window = \"2min\"\n");
    EXPECT_EQ(huge, "plant.toml:4: lines[0].late_reply_window: expected 1ms..1min (e.g. \"500ms\", default: the line's timeout)");
}

// RS-485 direction control and the guard are the link URL's options of those names, set by keys
// of the line that override the URL's; a line without a serial port has neither.
TEST(GatewayConfig, Rs485AndGuardKeysSetTheSerialLine) {
    auto config = parse("[[lines]]\nname = \"l1\"\nlink = \"rtu:/dev/ttyUSB0?rs485=1&guard=2ms\"\nrs485 = \"auto\"\n"
                        "rs485_delay_before = \"2ms\"\nrs485_delay_after = \"3ms\"\nguard = \"4.5c\"\n");
    ASSERT_TRUE(config) << config.error().message;
    const auto& serial = config->lines[0].link.serial;
    EXPECT_EQ(serial.rs485, transport::Rs485::if_supported);
    EXPECT_EQ(serial.rs485_delay_before, std::chrono::milliseconds(2));
    EXPECT_EQ(serial.rs485_delay_after, std::chrono::milliseconds(3));
    EXPECT_EQ(serial.guard.characters, 4.5);
    EXPECT_EQ(serial.guard.time, std::chrono::microseconds(0));

    auto on = parse("[[lines]]\nname = \"l1\"\nlink = \"rtu:/dev/ttyUSB0\"\nrs485 = true\n");
    ASSERT_TRUE(on) << on.error().message;
    EXPECT_EQ(on->lines[0].link.serial.rs485, transport::Rs485::on);

    EXPECT_EQ(error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:/dev/ttyUSB0\"\nrs485 = \"yes\"\n"),
              "plant.toml:4: lines[0].rs485: expected true, false or \"auto\"");
    EXPECT_THAT(error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:/dev/ttyUSB0\"\nguard = \"fast\"\n"),
                StartsWith("plant.toml:4: lines[0].guard: guard 'fast' is not valid"));
    EXPECT_THAT(error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:/dev/ttyUSB0\"\nrs485_delay_after = \"2s\"\n"),
                StartsWith("plant.toml:4: lines[0].rs485_delay_after: expected 1ms..1s"));
    EXPECT_EQ(error_of("[[lines]]\nname = \"plc\"\nlink = \"tcp://192.0.2.7:502\"\nguard = \"5ms\"\n"),
              "plant.toml:4: lines[0].guard: guard applies to a serial line only (this link is tcp://192.0.2.7:502)");
}

// Several requests at once only where replies say which request they answer: Modbus TCP.
TEST(GatewayConfig, MaxInFlightIsOneOnASerialLineAndBoundedOnAModbusTcpLine) {
    auto config = parse("[[lines]]\nname = \"plc\"\nlink = \"tcp://192.0.2.7:502\"\nmax_in_flight = 8\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->lines[0].max_in_flight, 8U);
    auto serial = parse("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\n");
    ASSERT_TRUE(serial) << serial.error().message;
    EXPECT_EQ(serial->lines[0].max_in_flight, 1U);
    EXPECT_TRUE(parse("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\nmax_in_flight = 1\n"));

    const std::string rtu = error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\nmax_in_flight = 4\n");
    EXPECT_EQ(rtu, "plant.toml:4: lines[0].max_in_flight: a rtu line carries one request at a time; more than 1 needs a "
                   "Modbus TCP device (link = \"tcp://host:502\"), whose replies carry the request's transaction id");
    const std::string device_server =
        error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu+tcp://192.0.2.8:4001\"\nmax_in_flight = 2\n");
    EXPECT_THAT(device_server, HasSubstr("a rtu+tcp line carries one request at a time")) << device_server;
    const std::string zero = error_of("[[lines]]\nname = \"plc\"\nlink = \"tcp://192.0.2.7:502\"\nmax_in_flight = 0\n");
    EXPECT_EQ(zero, "plant.toml:4: lines[0].max_in_flight: 0 is out of range (expected an integer 1..64)");
}

TEST(GatewayConfig, ABadDurationNamesTheKeyAndTheForm) {
    const std::string poll = error_of(one_device("device = \"tc10@3\"\npoll = \"fast\"\n"));
    EXPECT_THAT(poll, StartsWith("plant.toml:8: lines[0].devices[0].poll: 'fast' is not a duration")) << poll;
    EXPECT_THAT(poll, HasSubstr("500ms")) << poll;

    const std::string zero = error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\ntimeout = \"0ms\"\n");
    EXPECT_THAT(zero, StartsWith("plant.toml:4: lines[0].timeout: '0ms' is too short: give at least 1ms")) << zero;

    const std::string number = error_of(one_device("device = \"tc10@3\"\npoll = 1000\n"));
    EXPECT_THAT(number, StartsWith("plant.toml:8: lines[0].devices[0].poll: expected a duration string")) << number;
}

TEST(GatewayConfig, ABadLinkPassesTheLinkParsersWordsOn) {
    const std::string message = error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:/dev/ttyUSB0?baud=12345\"\n");
    EXPECT_THAT(message, StartsWith("plant.toml:3: lines[0].link: ")) << message;
    EXPECT_THAT(message, HasSubstr("12345")) << message;
    EXPECT_THAT(message, HasSubstr("not a supported rate")) << message;
}

TEST(GatewayConfig, AnUnknownProfileOrBadUnitIsNamed) {
    const std::string profile = error_of(one_device("device = \"oven@3\"\n"));
    EXPECT_THAT(profile, StartsWith("plant.toml:7: lines[0].devices[0].device: ")) << profile;
    EXPECT_THAT(profile, HasSubstr("oven")) << profile;
    EXPECT_THAT(profile, HasSubstr("tc10")) << profile;  // the known ids are listed

    const std::string unit = error_of(one_device("device = \"tc10@300\"\n"));
    EXPECT_THAT(unit, StartsWith("plant.toml:7: lines[0].devices[0].device: ")) << unit;
    EXPECT_THAT(unit, HasSubstr("1..255")) << unit;
}

TEST(GatewayConfig, TwoDevicesOnALineWithOneUnitAreRefused) {
    const std::string message = error_of(one_device("device = \"tc10@3\"\n\n[[lines.devices]]\nname = \"oven2\"\ndevice = \"ac20@3\"\n"));
    EXPECT_THAT(message, StartsWith("plant.toml:11: lines[0].devices[1].device: unit 3 is already used by oven1")) << message;
    EXPECT_THAT(message, HasSubstr("lines[0].devices[0], line 5")) << message;
}

TEST(GatewayConfig, ATcpUnitClashAcrossLinesNamesBothAndSuggestsAMapping) {
    const std::string text = one_device("device = \"tc10@3\"\n") +  // 1-7
                             "\n"                                   // 8
                             "[[lines]]\n"                          // 9
                             "name = \"l2\"\n"                      // 10
                             "link = \"tcp://192.0.2.1:502\"\n"     // 11
                             "[[lines.devices]]\n"                  // 12
                             "name = \"oven2\"\n"                   // 13
                             "device = \"tc10@3\"\n";               // 14
    const std::string message = error_of(text);
    EXPECT_THAT(message, StartsWith("plant.toml:14: lines[1].devices[0].device: Modbus TCP unit 3 would be both oven1")) << message;
    EXPECT_THAT(message, HasSubstr("oven2")) << message;
    EXPECT_THAT(message, HasSubstr("tcp_unit = 1")) << message;  // the lowest free unit

    // Mapped away, both are served; a clash with an explicit tcp_unit points at that key.
    EXPECT_TRUE(parse(text + "tcp_unit = 4\n"));
    const std::string mapped = error_of(text + "tcp_unit = 3\n");
    EXPECT_THAT(mapped, StartsWith("plant.toml:15: lines[1].devices[0].tcp_unit: Modbus TCP unit 3")) << mapped;

    // Without the Modbus TCP front no client names a unit: a plant of any size is taken.
    EXPECT_TRUE(parse(text + "\n[modbus_tcp]\nenabled = false\n"));
}

TEST(GatewayConfig, AnUnknownParameterNamesTheDeviceAndTheName) {
    const std::string message = error_of(one_device("device = \"tc10@3\"\nparameters = [\"measured_value\",\n  \"mesured_value\"]\n"));
    EXPECT_THAT(message, StartsWith("plant.toml:9: lines[0].devices[0].parameters[1]: device oven1: ")) << message;
    EXPECT_THAT(message, HasSubstr("\"mesured_value\"")) << message;

    const std::string not_a_name = error_of(one_device("device = \"tc10@3\"\nparameters = [1]\n"));
    EXPECT_THAT(not_a_name, StartsWith("plant.toml:8: lines[0].devices[0].parameters[0]: expected a parameter name")) << not_a_name;
}

TEST(GatewayConfig, ABadListenAddressIsRefused) {
    for (const char* listen : {"127.0.0.1", "127.0.0.1:65536", ":1502", "::1:1502", "[::1]1502", "host:port"}) {
        const std::string message = error_of(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nlisten = \"" + listen + "\"\n");
        EXPECT_THAT(message, StartsWith(fmt::format("plant.toml:9: modbus_tcp.listen: \"{}\" is not an address to listen on", listen)))
            << message;
        EXPECT_THAT(message, HasSubstr("HOST:PORT")) << message;
    }
}

// An address that reads as numbers must be one: the start could not resolve it.
TEST(GatewayConfig, AListenAddressThatIsNoAddressIsRefused) {
    for (const char* listen : {"999.1.1.1:80", "1.2.3:80", "[::g]:80", "bad_host:80", "-x:80"}) {
        const std::string http = error_of(one_device("device = \"tc10@3\"\n") + "[http]\nlisten = \"" + listen + "\"\n");
        EXPECT_THAT(http, StartsWith(fmt::format("plant.toml:9: http.listen: \"{}\" is not an address to listen on", listen)))
            << http;
        EXPECT_THAT(http, HasSubstr("e.g. \"127.0.0.1:8080\"")) << http;
        const std::string tcp = error_of(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nlisten = \"" + listen + "\"\n");
        EXPECT_THAT(tcp, StartsWith(fmt::format("plant.toml:9: modbus_tcp.listen: \"{}\" is not an address to listen on", listen)))
            << tcp;
    }
    for (const char* listen : {"0.0.0.0:80", "192.168.1.10:8080", "[::]:8080", "[fe80::1]:80", "gateway.plant-1.local:80"}) {
        auto config = parse(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nlisten = \"" + listen + "\"\n");
        EXPECT_TRUE(config) << listen << ": " << config.error().message;
    }
}

// A device's unit is its address on the line: left out, it would silently be 1.
TEST(GatewayConfig, ADeviceWithoutItsUnitIsRefused) {
    EXPECT_THAT(error_of(one_device("device = \"tc10\"\n")),
                StartsWith("plant.toml:7: lines[0].devices[0].device: \"tc10\" names no unit: add the device's Modbus address "
                           "after '@' (e.g. \"tc10@1\")"));
}

// A device on a line of a protocol its manual does not list would never answer a poll.
TEST(GatewayConfig, ADeviceOnALineOfAProtocolItDoesNotSpeakIsRefused) {
    const auto device_on = [](const std::string& link, const std::string& device) {
        return "[[lines]]\nname = \"l1\"\nlink = \"" + link + "\"\n[[lines.devices]]\nname = \"oven1\"\ndevice = \"" + device +
               "\"\n";
    };
    EXPECT_THAT(error_of(device_on("linking:/dev/ttyS1?baud=9600", "tc10@3")),
                StartsWith("plant.toml:6: lines[0].devices[0].device: device oven1 (tc10) does not speak linking, the protocol "
                           "of line l1 (it speaks rtu): put it on a line of its own protocol"));
    EXPECT_THAT(error_of(device_on("ascii:/dev/ttyS1?baud=9600", "ac20@3")),
                HasSubstr("device oven1 (ac20) does not speak ascii, the protocol of line l1 (it speaks rtu)"));
    EXPECT_THAT(error_of(device_on("ascii:virtual?baud=9600", "tc10@3")), HasSubstr("does not speak ascii"));
    // What it speaks; RTU through a device server is RTU; behind a Modbus TCP link, the far side's business.
    for (const auto& [link, device] : std::vector<std::pair<std::string, std::string>>{
             {"linking:/dev/ttyS1?baud=9600", "rampsoak@3"}, {"ascii:/dev/ttyS1?baud=9600", "rampsoak@3"},
             {"rtu+tcp://192.0.2.1:4001", "tc10@3"}, {"tcp://192.0.2.1:502", "tc10@3"}}) {
        auto config = parse(device_on(link, device));
        EXPECT_TRUE(config) << link << " " << device << ": " << config.error().message;
    }
}

// Port 0 asks the kernel for a free port (printed when the gateway starts): what tests use.
TEST(GatewayConfig, PortZeroListensOnAnyFreePort) {
    auto config = parse(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nlisten = \"127.0.0.1:0\"\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->modbus_tcp.port, 0);
    EXPECT_EQ(config->modbus_tcp.host, "127.0.0.1");
}

TEST(GatewayConfig, NamesMustBeUniqueAndFitForTopics) {
    const std::string lines = error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\n"
                                       "[[lines]]\nname = \"l1\"\nlink = \"tcp://192.0.2.1:502\"\n");
    EXPECT_EQ(lines, "plant.toml:5: lines[1].name: \"l1\" is already the name of lines[0] (line 1); line names must be unique");

    // Device names are unique across the gateway, not only on their line.
    const std::string devices = error_of(one_device("device = \"tc10@3\"\n") +
                                         "[[lines]]\nname = \"l2\"\nlink = \"tcp://192.0.2.1:502\"\n"
                                         "[[lines.devices]]\nname = \"oven1\"\ndevice = \"tc10@4\"\n");
    EXPECT_EQ(devices, "plant.toml:12: lines[1].devices[0].name: \"oven1\" is already the name of lines[0].devices[0] (line 5); "
                       "device names must be unique");

    for (const char* name : {"", "oven 1", "oven/1", "ofen\xc3\xa4"}) {
        const std::string message = error_of(std::string("[[lines]]\nname = \"") + name + "\"\nlink = \"rtu:virtual\"\n");
        EXPECT_THAT(message, StartsWith("plant.toml:2: lines[0].name: ")) << message;
        EXPECT_THAT(message, HasSubstr("letters, digits, '-' and '_'")) << message;
    }
}

TEST(GatewayConfig, RequiredPartsAreNamedWhenMissing) {
    EXPECT_EQ(error_of("[modbus_tcp]\nwrites = false\n"),
              "plant.toml:1: lines: no lines: at least one [[lines]] table is needed, with a name and a link");
    EXPECT_THAT(error_of("\n\nlines = []\n"), StartsWith("plant.toml:3: lines: no lines"));
    EXPECT_THAT(error_of("[lines]\nname = \"l1\"\n"), StartsWith("plant.toml:1: lines: expected [[lines]] tables"));
    EXPECT_EQ(error_of("\n[[lines]]\nname = \"l1\"\n"), "plant.toml:2: lines[0]: missing `link` (e.g. link = \"rtu:/dev/ttyUSB0?baud=19200\")");
    EXPECT_THAT(error_of("[[lines]]\nlink = \"rtu:virtual\"\n"), StartsWith("plant.toml:1: lines[0]: missing `name`"));
    EXPECT_THAT(error_of(one_device("")), StartsWith("plant.toml:5: lines[0].devices[0]: missing `device` (e.g. device = \"tc10@3\")"));
}

TEST(GatewayConfig, IntegersAndBooleansAreRangeAndTypeChecked) {
    EXPECT_EQ(error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\nretries = 11\n"),
              "plant.toml:4: lines[0].retries: 11 is out of range (expected an integer 0..10)");
    EXPECT_EQ(error_of(one_device("device = \"tc10@3\"\ntcp_unit = 0\n")),
              "plant.toml:8: lines[0].devices[0].tcp_unit: 0 is out of range (expected an integer 1..247)");
    EXPECT_EQ(error_of(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nwrites = \"yes\"\n"),
              "plant.toml:9: modbus_tcp.writes: expected true or false");
}

TEST(GatewayConfig, AVirtualLinkIsASimulatedLineWithItsSpeedAndSeed) {
    auto config = parse(one_device("device = \"tc10@3\"\n"));
    ASSERT_TRUE(config) << config.error().message;
    ASSERT_TRUE(config->lines[0].simulation.has_value());
    EXPECT_EQ(config->lines[0].simulation->speed, 1.0);
    EXPECT_EQ(config->lines[0].simulation->seed, 1u);

    auto fast = parse("[[lines]]\nname = \"l1\"\nlink = \"ascii:virtual?baud=9600\"\nspeed = 30\nseed = 7\n");
    ASSERT_TRUE(fast) << fast.error().message;
    ASSERT_TRUE(fast->lines[0].simulation.has_value());
    EXPECT_EQ(fast->lines[0].simulation->speed, 30.0);
    EXPECT_EQ(fast->lines[0].simulation->seed, 7u);
    EXPECT_EQ(parse("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\nspeed = 0.5\n")->lines[0].simulation->speed, 0.5);

    auto real = parse(tc10_line_for_simulation());
    ASSERT_TRUE(real) << real.error().message;
    EXPECT_FALSE(real->lines[0].simulation.has_value());
}

TEST(GatewayConfig, SpeedAndSeedAreRefusedOnARealLineAndRangeChecked) {
    EXPECT_EQ(error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:/dev/ttyUSB0\"\nspeed = 30\n"),
              "plant.toml:4: lines[0].speed: speed applies to a simulated line only (link = \"rtu:virtual?baud=19200\"); "
              "remove it for a line with a real device");
    EXPECT_EQ(error_of("[[lines]]\nname = \"l1\"\nlink = \"tcp://127.0.0.1:502\"\nseed = 3\n"),
              "plant.toml:4: lines[0].seed: seed applies to a simulated line only (link = \"rtu:virtual?baud=19200\"); "
              "remove it for a line with a real device");
    EXPECT_EQ(error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\nspeed = 0\n"),
              "plant.toml:4: lines[0].speed: 0 is out of range (expected a number 0.001..100000)");
    EXPECT_EQ(error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\nspeed = \"fast\"\n"),
              "plant.toml:4: lines[0].speed: expected a number 0.001..100000");
    EXPECT_EQ(error_of("[[lines]]\nname = \"l1\"\nlink = \"rtu:virtual\"\nseed = -1\n"),
              "plant.toml:4: lines[0].seed: -1 is out of range (expected an integer 0..4294967295)");
}

// The lines of a message of several mistakes.
std::vector<std::string> lines_of(const std::string& message) {
    std::vector<std::string> lines;
    std::size_t start = 0;
    for (std::size_t end = message.find('\n'); end != std::string::npos; end = message.find('\n', start)) {
        lines.push_back(message.substr(start, end - start));
        start = end + 1;
    }
    lines.push_back(message.substr(start));
    return lines;
}

TEST(GatewayConfigMistakes, EveryIndependentMistakeIsSaidWithItsLineAndTheyAreCounted) {
    // Six mistakes, one in each of six tables; none depends on another.
    const std::string text = R"toml([[lines]]
name = "furnace-line"
link = "rtu:virtual?baud=19200"
timeout = "fast"

[[lines.devices]]
name = "oven1"
device = "tc10@3"

[[lines.devices]]
name = "oven1"
device = "tc10@4"

[modbus_tcp]
listen = "127.0.0.1:99999"

[log]
file = "gateway.log"

[mqtt]
broker = "mqtt://127.0.0.1:1883"
max_payload = 8

[http]
read_timeout = "1ms"
)toml";
    const std::string message = error_of(text);
    const auto lines = lines_of(message);
    ASSERT_EQ(lines.size(), 7u) << message;
    EXPECT_THAT(lines[0], StartsWith("plant.toml:4: lines[0].timeout: 'fast' is not a duration"));
    EXPECT_EQ(lines[1], "plant.toml:11: lines[0].devices[1].name: \"oven1\" is already the name of lines[0].devices[0] "
                        "(line 6); device names must be unique");
    EXPECT_THAT(lines[2], StartsWith("plant.toml:15: modbus_tcp.listen: \"127.0.0.1:99999\" is not an address to listen on"));
    EXPECT_EQ(lines[3], "plant.toml:18: log.file: unknown key (allowed here: level, statistics)");
    EXPECT_EQ(lines[4], "plant.toml:22: mqtt.max_payload: 8 is out of range (expected an integer 16..65536)");
    EXPECT_EQ(lines[5], "plant.toml:25: http.read_timeout: expected 100ms..10min (e.g. \"10s\")");
    EXPECT_EQ(lines[6], "6 mistakes in plant.toml");
}

TEST(GatewayConfigMistakes, EveryUnknownKeyAndEveryBadValueOfATableIsSaid) {
    const std::string message = error_of(one_device("device = \"tc10@3\"\npol = \"1s\"\nidentify = \"no\"\ntcp_unit = 0\n"
                                                    "parameters = [\"no_such\", \"set_point\", 3]\n") +
                                         "[modbus_tcp]\nwrites = \"yes\"\nidle = \"1m\"\n");
    const auto lines = lines_of(message);
    ASSERT_EQ(lines.size(), 8u) << message;
    EXPECT_THAT(lines[0], StartsWith("plant.toml:8: lines[0].devices[0].pol: unknown key"));
    EXPECT_THAT(lines[1], StartsWith("plant.toml:9: lines[0].devices[0].identify: expected true or false"));
    EXPECT_THAT(lines[2], StartsWith("plant.toml:10: lines[0].devices[0].tcp_unit: 0 is out of range"));
    EXPECT_THAT(lines[3], StartsWith("plant.toml:11: lines[0].devices[0].parameters[0]: device oven1: "));
    EXPECT_THAT(lines[4], StartsWith("plant.toml:11: lines[0].devices[0].parameters[2]: expected a parameter name"));
    EXPECT_THAT(lines[5], StartsWith("plant.toml:13: modbus_tcp.writes: expected true or false"));
    EXPECT_THAT(lines[6], StartsWith("plant.toml:14: modbus_tcp.idle: unknown key"));
    EXPECT_EQ(lines[7], "7 mistakes in plant.toml");
}

TEST(GatewayConfigMistakes, EachLineAndDeviceIsCheckedWhateverIsWrongWithAnother) {
    // Two lines of one port, a unit twice on the first, and two devices on one Modbus TCP unit:
    // each clash is said once, at the later of the two.
    const std::string message = error_of(R"toml([[lines]]
name = "a"
link = "rtu:/dev/ttyUSB0"

[[lines.devices]]
name = "one"
device = "tc10@3"

[[lines.devices]]
name = "two"
device = "ac20@3"

[[lines]]
name = "b"
link = "rtu:/dev/ttyUSB0"

[[lines]]
name = "c"
link = "tcp://192.0.2.7:502"

[[lines.devices]]
name = "three"
device = "tc10@3"
)toml");
    const auto lines = lines_of(message);
    ASSERT_EQ(lines.size(), 5u) << message;
    EXPECT_THAT(lines[0], StartsWith("plant.toml:11: lines[0].devices[1].device: unit 3 is already used by one"));
    EXPECT_THAT(lines[1], StartsWith("plant.toml:11: lines[0].devices[1].device: Modbus TCP unit 3 would be both one"));
    EXPECT_THAT(lines[2], StartsWith("plant.toml:15: lines[1].link: /dev/ttyUSB0 is already the port of line a"));
    EXPECT_THAT(lines[3], StartsWith("plant.toml:23: lines[2].devices[0].device: Modbus TCP unit 3 would be both one"));
    EXPECT_EQ(lines[4], "4 mistakes in plant.toml");
}

TEST(GatewayConfigMistakes, WhatAMistakeMakesMeaninglessIsNotCheckedToo) {
    // A link that does not parse: its serial keys, its simulation keys and its devices' protocol
    // are not judged against it; the device's own keys still are.
    const std::string bad_link = error_of(R"toml([[lines]]
name = "a"
link = "rtu:/dev/ttyUSB0?baud=12345"
rs485 = true
speed = 3

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "often"
)toml");
    const auto link_lines = lines_of(bad_link);
    ASSERT_EQ(link_lines.size(), 3u) << bad_link;
    EXPECT_THAT(link_lines[0], StartsWith("plant.toml:3: lines[0].link: "));
    EXPECT_THAT(link_lines[1], StartsWith("plant.toml:10: lines[0].devices[0].poll: "));
    // An unknown profile: the parameters, named in its terms, are not looked up.
    EXPECT_THAT(error_of(one_device("device = \"nosuch@3\"\nparameters = [\"whatever\"]\n")),
                AllOf(StartsWith("plant.toml:7: lines[0].devices[0].device: "), Not(HasSubstr("\n"))));
    // A wrong tcp_unit clashes with nothing: only its own mistake is said.
    EXPECT_THAT(error_of(one_device("device = \"tc10@3\"\n\n[[lines.devices]]\nname = \"b\"\ndevice = \"tc10@4\"\n"
                                    "tcp_unit = 300\n")),
                AllOf(StartsWith("plant.toml:12: lines[0].devices[1].tcp_unit: 300 is out of range"), Not(HasSubstr("\n"))));
    // A file that is not TOML has nothing else to check.
    EXPECT_THAT(error_of("[[lines]]\nname = \"a\nlink = 3\n[log]\nlevel = \"loud\"\n"),
                AllOf(StartsWith("plant.toml:2:"), HasSubstr("TOML syntax error"), Not(HasSubstr("\n"))));
}

TEST(GatewayConfig, LogLevelAndStatisticsIntervalAreRead) {
    auto defaults = parse(one_device("device = \"tc10@3\"\n"));
    ASSERT_TRUE(defaults) << defaults.error().message;
    EXPECT_EQ(defaults->log.level, LogConfig::Level::info);
    EXPECT_EQ(defaults->log.statistics, std::chrono::seconds(60));

    auto set = parse(one_device("device = \"tc10@3\"\n") + "[log]\nlevel = \"warning\"\nstatistics = \"5m\"\n");
    ASSERT_TRUE(set) << set.error().message;
    EXPECT_EQ(set->log.level, LogConfig::Level::warning);
    EXPECT_EQ(set->log.statistics, std::chrono::minutes(5));
    auto off = parse(one_device("device = \"tc10@3\"\n") + "[log]\nstatistics = \"off\"\n");
    ASSERT_TRUE(off) << off.error().message;
    EXPECT_EQ(off->log.statistics, std::chrono::milliseconds(0));
}

TEST(GatewayConfig, BadLogSettingsSayWhatIsExpected) {
    EXPECT_EQ(error_of(one_device("device = \"tc10@3\"\n") + "[log]\nlevel = \"loud\"\n"),
              "plant.toml:9: log.level: \"loud\" is not a log level (expected \"debug\", \"info\", \"warning\" or \"error\")");
    EXPECT_EQ(error_of(one_device("device = \"tc10@3\"\n") + "[log]\nstatistics = \"100ms\"\n"),
              "plant.toml:9: log.statistics: expected at least 1s, or \"off\" (closer together they would bury the log in "
              "figures; e.g. \"60s\", or \"off\" for only at exit)");
    // "0s" is below the real minimum, which the error names (not the 1ms of other durations).
    EXPECT_THAT(error_of(one_device("device = \"tc10@3\"\n") + "[log]\nstatistics = \"0s\"\n"),
                StartsWith("plant.toml:9: log.statistics: expected at least 1s"));
    EXPECT_THAT(error_of(one_device("device = \"tc10@3\"\n") + "[log]\nstatistics = \"often\"\n"),
                StartsWith("plant.toml:9: log.statistics: 'often' is not a duration"));
    EXPECT_EQ(error_of(one_device("device = \"tc10@3\"\n") + "[log]\nfile = \"x\"\n"),
              "plant.toml:9: log.file: unknown key (allowed here: level, statistics)");
}

// --- The plan ---------------------------------------------------------------------------------

// Wire time of one RTU read of `registers` holding registers, in microseconds, as the codec
// times characters (rounded up to whole microseconds): an 8-byte request, a 5 + 2n byte reply,
// and a 3.5-character silence before each.
long long rtu_read_wire_us(unsigned registers, unsigned baud, unsigned bits) {
    const auto ceil_div = [](unsigned long long a, unsigned long long b) { return static_cast<long long>((a + b - 1) / b); };
    const long long character = ceil_div(bits * 1'000'000ull, baud);
    const long long t3_5 = ceil_div(bits * 7'000'000ull, 2ull * baud);
    return (8 + 5 + 2 * static_cast<long long>(registers)) * character + 2 * t3_5;
}

std::string plan_of(const std::string& text) {
    auto config = parse(text);
    if (!config) {
        ADD_FAILURE() << config.error().message;
        return {};
    }
    return describe_plan(*config);
}

// tc10@3 on 19200 8E1 (11 bits a character). measured_value (word 1) and set_point (717) take
// their decimals from decimal_point (641) and their unit from temperature_unit (644): two
// single-word reads and one of 641-644, since the TC10 refuses reads across unmapped words and
// 16 words is its limit.
std::string tc10_line(const std::string& poll) {
    return "[[lines]]\nname = \"l1\"\nlink = \"rtu:/dev/ttyUSB0?baud=19200&parity=even\"\n"
           "[[lines.devices]]\nname = \"oven1\"\ndevice = \"tc10@3\"\npoll = \"" + poll + "\"\n"
           "parameters = [\"measured_value\", \"set_point\"]\n";
}

// A port that is not there is a warning in the plan, not an error: the gateway starts with that
// line down and opens it when it appears. /dev/null exists; the second path does not.
TEST(GatewayConfigPlan, APortMissingNowIsAWarning) {
    const std::string missing = "/nonexistent-loopwire-port/ttyUSB9";
    const std::string plan = plan_of("[[lines]]\nname = \"present\"\nlink = \"rtu:/dev/null\"\n"
                                     "[[lines]]\nname = \"absent\"\nlink = \"rtu:" + missing + "\"\n");
    EXPECT_THAT(plan, HasSubstr("warning: port " + missing + " does not exist now; the gateway will start with this line "
                                "down and open it when it appears")) << plan;
    EXPECT_THAT(plan, Not(HasSubstr("warning: port /dev/null"))) << plan;
}

// A port that is there must be a terminal: /dev/null and /dev/zero are character devices too,
// and a line on one would stay down for ever. A pseudo-terminal (a test's, socat's) is one.
TEST(GatewayConfigPlan, ACharacterDeviceThatIsNoTerminalIsRefused) {
    for (const std::string port : {"/dev/null", "/dev/zero"}) {
        auto config = parse("[[lines]]\nname = \"l1\"\nlink = \"rtu:" + port + "?baud=9600\"\n");
        ASSERT_TRUE(config) << config.error().message;
        auto checked = check_environment(*config);
        ASSERT_FALSE(checked) << port << " was taken for a serial port";
        EXPECT_THAT(checked.error().message,
                    StartsWith("plant.toml:3: line l1: " + port + " is a character device of the kernel's \"mem\" class (as "
                               "/dev/null and /dev/zero are), not a serial port: name the adapter's device"));
    }
    const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
    ASSERT_GE(master, 0);
    ASSERT_EQ(::grantpt(master), 0);
    ASSERT_EQ(::unlockpt(master), 0);
    const std::string terminal = ::ptsname(master);
    auto config = parse("[[lines]]\nname = \"l1\"\nlink = \"rtu:" + terminal + "?baud=9600\"\n");
    ASSERT_TRUE(config) << config.error().message;
    auto checked = check_environment(*config);
    EXPECT_TRUE(checked) << checked.error().message;
    ::close(master);
}

TEST(GatewayConfigPlan, LoadIsTheWireTimeOfEachPollOverItsInterval) {
    const long long per_poll_us = 2 * rtu_read_wire_us(1, 19200, 11) + rtu_read_wire_us(4, 19200, 11);
    ASSERT_EQ(per_poll_us, 2 * ((8 + 7) * 573 + 2 * 2006) + (8 + 13) * 573 + 2 * 2006);  // 573 us a character, t3.5 = 2006 us
    const std::string plan = plan_of(tc10_line("1s"));
    EXPECT_THAT(plan, HasSubstr("line l1: rtu:/dev/ttyUSB0")) << plan;
    EXPECT_THAT(plan, HasSubstr("device oven1: tc10@3, Modbus TCP unit 3, every 1s: 2 parameters in 3 requests per poll")) << plan;
    const double load = 100.0 * static_cast<double>(per_poll_us) / 1e6;
    EXPECT_THAT(plan, HasSubstr(fmt::format("estimated line load: {:.1f} % of wire time\n", load))) << plan;
    EXPECT_THAT(plan, HasSubstr("estimated line load: 4.1 % of wire time")) << plan;
    EXPECT_THAT(plan, Not(HasSubstr("fall behind"))) << plan;
    EXPECT_THAT(plan, HasSubstr("Modbus TCP: listening on 127.0.0.1:1502, writes allowed")) << plan;
}

TEST(GatewayConfigPlan, AnOverloadedLineIsWarnedAbout) {
    const long long per_poll_us = 2 * rtu_read_wire_us(1, 19200, 11) + rtu_read_wire_us(4, 19200, 11);
    const double load = 100.0 * static_cast<double>(per_poll_us) / 10e3;  // every 10 ms
    const std::string plan = plan_of(tc10_line("10ms"));
    EXPECT_THAT(plan, HasSubstr(fmt::format("estimated line load: {:.1f} % of wire time\n", load))) << plan;
    EXPECT_THAT(plan, HasSubstr("412.6 %")) << plan;
    EXPECT_THAT(plan, HasSubstr("over 100 %: polls will fall behind")) << plan;
}

// Polls and clients take turns: polls needing more than half the line fall behind when
// clients keep it busy.
TEST(GatewayConfigPlan, ALineWhosePollsNeedOverHalfIsWarnedAbout) {
    const std::string plan = plan_of(tc10_line("60ms"));
    EXPECT_THAT(plan, HasSubstr("estimated line load: 68.8 % of wire time")) << plan;
    EXPECT_THAT(plan, HasSubstr("over 50 %: while Modbus TCP clients keep the line busy the polls get half of it")) << plan;
    EXPECT_THAT(plan, Not(HasSubstr("over 100 %"))) << plan;
    EXPECT_THAT(plan_of(tc10_line("100ms")), Not(HasSubstr("over 50 %"))) << "41.3 %";
}

TEST(GatewayConfigPlan, LoadsOfDevicesOnOneLineAddUp) {
    const std::string text = tc10_line("1s") + "[[lines.devices]]\nname = \"oven2\"\ndevice = \"tc10@4\"\npoll = \"500ms\"\n"
                                               "parameters = [\"measured_value\", \"set_point\"]\n";
    const long long per_poll_us = 2 * rtu_read_wire_us(1, 19200, 11) + rtu_read_wire_us(4, 19200, 11);
    const double load = 100.0 * static_cast<double>(per_poll_us) / 1e6 + 100.0 * static_cast<double>(per_poll_us) / 500e3;
    const std::string plan = plan_of(text);
    EXPECT_THAT(plan, HasSubstr(fmt::format("estimated line load: {:.1f} % of wire time\n", load))) << plan;
    EXPECT_THAT(plan, HasSubstr("12.4 %")) << plan;
}

TEST(GatewayConfigPlan, TheDefaultWatchListIsPolledWhenNoneIsNamed) {
    const std::string plan = plan_of(one_device("device = \"tc10@3\"\n"));
    // measured_value, set_point, operating_set_point, output_power, alarm_status, control_state
    // (client/monitor_names.cpp)
    EXPECT_THAT(plan, HasSubstr("6 parameters (default watch list)")) << plan;
}

TEST(GatewayConfigPlan, TcpAndAsciiLinksSayWhatTheEstimateIs) {
    const std::string tcp = plan_of("[[lines]]\nname = \"l1\"\nlink = \"tcp://192.0.2.1:502\"\n"
                                    "[[lines.devices]]\nname = \"oven1\"\ndevice = \"tc10@3\"\n");
    EXPECT_THAT(tcp, HasSubstr("no wire-time estimate for TCP links")) << tcp;
    EXPECT_THAT(tcp, Not(HasSubstr("estimated line load"))) << tcp;

    // ASCII: each RTU byte but the CRC as two characters, plus LRC (2), ':' and CR LF; 7E1 is
    // 10 bits a character. The ramp/soak controller's words 1 and 2 (no decimals or unit read from
    // other words) in one read: request 8 RTU bytes -> 17 characters, reply 9 -> 19 characters.
    const std::string ascii = plan_of("[[lines]]\nname = \"l1\"\nlink = \"ascii:/dev/ttyS1?baud=9600&parity=even&data=7\"\n"
                                      "[[lines.devices]]\nname = \"ramp1\"\ndevice = \"rampsoak@3\"\npoll = \"1s\"\n"
                                      "parameters = [\"output_limit\", \"auto_tuning\"]\n");
    const long long character_us = (10 * 1'000'000 + 9600 - 1) / 9600;  // 1042 us
    const double load = 100.0 * static_cast<double>((17 + 19) * character_us) / 1e6;
    EXPECT_THAT(ascii, HasSubstr(fmt::format("estimated line load: {:.1f} % of wire time (approximate", load))) << ascii;
}

TEST(GatewayConfigPlan, ShowsTheLineSettingsAndTheTcpFront) {
    const std::string plan = plan_of(example);
    EXPECT_THAT(plan, StartsWith("plant.toml: 1 line\n")) << plan;
    EXPECT_THAT(plan, HasSubstr("(timeout 300ms, 1 retry)")) << plan;
    EXPECT_THAT(plan, HasSubstr("Modbus TCP unit 13")) << plan;
    EXPECT_THAT(plan, HasSubstr("at most 64 client(s) at once (the idlest closed for a newcomer), idle ones closed after 1m"))
        << plan;
    const std::string off = plan_of(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nenabled = false\n");
    EXPECT_THAT(off, HasSubstr("Modbus TCP: disabled")) << off;
    EXPECT_THAT(plan, Not(HasSubstr("cache"))) << plan;
}

TEST(GatewayConfigPlan, ShowsTheReadCache) {
    const std::string plan = plan_of(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nmax_age = \"500ms\"\n");
    EXPECT_THAT(plan,
                HasSubstr("Modbus TCP: listening on 127.0.0.1:1502, writes allowed\n"
                          "  reads (function codes 1-4) answered from cache up to 500ms old; a write through a unit "
                          "empties its cache\n"))
        << plan;
    const std::string seconds = plan_of(one_device("device = \"tc10@3\"\n") + "[modbus_tcp]\nmax_age = \"2s\"\n");
    EXPECT_THAT(seconds, HasSubstr("answered from cache up to 2s old")) << seconds;
}

// --- Loading a file ---------------------------------------------------------------------------

class GatewayConfigFile : public ::testing::Test {
protected:
    void SetUp() override {
        std::string pattern = (fs::temp_directory_path() / "loopwire-gateway-config-XXXXXX").string();
        ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
        dir = pattern;
    }
    void TearDown() override { fs::remove_all(dir); }
    fs::path write(const std::string& name, const std::string& text) const {
        const fs::path path = dir / name;
        std::ofstream(path, std::ios::binary) << text;
        return path;
    }
    fs::path dir;
};

TEST_F(GatewayConfigFile, ReadsTheFileAndNamesItInErrors) {
    const fs::path good = write("plant.toml", example);
    auto config = load_gateway_config(good, profiles());
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->source, good.string());
    EXPECT_EQ(config->lines.at(0).devices.at(0).name, "oven1");

    const fs::path bad = write("bad.toml", one_device("device = \"tc10@3\"\npoll = \"fast\"\n"));
    auto refused = load_gateway_config(bad, profiles());
    ASSERT_FALSE(refused);
    EXPECT_THAT(refused.error().message, StartsWith(bad.string() + ":8: lines[0].devices[0].poll: "));
}

TEST_F(GatewayConfigFile, MissingDirectoryAndOversizedFilesAreRefused) {
    auto missing = load_gateway_config(dir / "nope.toml", profiles());
    ASSERT_FALSE(missing);
    EXPECT_THAT(missing.error().message, HasSubstr("nope.toml: cannot read the gateway configuration"));

    auto directory = load_gateway_config(dir, profiles());
    ASSERT_FALSE(directory);
    EXPECT_THAT(directory.error().message, HasSubstr("is a directory, not a regular file"));

    // Comments only, so it would parse if it were read: the size alone refuses it.
    const fs::path huge = write("huge.toml", std::string(1024 * 1024, '#') + "\n");
    auto large = load_gateway_config(huge, profiles());
    ASSERT_FALSE(large);
    EXPECT_THAT(large.error().message, HasSubstr("too large"));
}

// ---------------------------------------------------------------------------------------------
// [mqtt]

TEST(GatewayConfig, WithoutAnMqttTableThereIsNoMqtt) {
    auto config = parse(one_device("device = \"tc10@3\"\n"));
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_FALSE(config->mqtt);
}

TEST(GatewayConfig, MqttSettingsAreRead) {
    auto config = parse(one_device("device = \"tc10@3\"\n") +
                        "[mqtt]\nbroker = \"mqtt://127.0.0.1:1884\"\nprefix = \"loopwire/plant1\"\nwrites = true\n"
                        "client_id = \"gw1\"\n");
    ASSERT_TRUE(config) << config.error().message;
    ASSERT_TRUE(config->mqtt);
    EXPECT_EQ(config->mqtt->broker, "mqtt://127.0.0.1:1884");
    EXPECT_EQ(config->mqtt->host, "127.0.0.1");
    EXPECT_EQ(config->mqtt->port, 1884);
    EXPECT_EQ(config->mqtt->prefix, "loopwire/plant1");
    EXPECT_TRUE(config->mqtt->writes);
    EXPECT_EQ(config->mqtt->client_id, "gw1");
    EXPECT_THAT(describe_plan(*config), HasSubstr("MQTT: mqtt://127.0.0.1:1884 under loopwire/plant1/, writes allowed"));
}

TEST(GatewayConfig, MqttDefaultsApplyToWhatIsLeftOut) {
    auto config = parse(one_device("device = \"tc10@3\"\n") + "[mqtt]\nbroker = \"mqtt://broker.local\"\n");
    ASSERT_TRUE(config) << config.error().message;
    ASSERT_TRUE(config->mqtt);
    EXPECT_EQ(config->mqtt->host, "broker.local");
    EXPECT_EQ(config->mqtt->port, 1883);
    EXPECT_EQ(config->mqtt->prefix, "loopwire/gateway");
    EXPECT_FALSE(config->mqtt->writes);  // writes from MQTT are opt-in
    EXPECT_EQ(config->mqtt->client_id, "");
    EXPECT_FALSE(config->mqtt->tls);
    EXPECT_EQ(config->mqtt->republish, std::chrono::minutes(5));
    EXPECT_EQ(config->mqtt->discovery, MqttConfig::Discovery::none);
    EXPECT_EQ(config->mqtt->discovery_prefix, "homeassistant");
    EXPECT_EQ(config->mqtt->gateway_name, "gateway");
    EXPECT_EQ(config->mqtt->max_payload, 1024u);

    auto ipv6 = parse(one_device("device = \"tc10@3\"\n") + "[mqtt]\nbroker = \"mqtt://[::1]:1883\"\n");
    ASSERT_TRUE(ipv6) << ipv6.error().message;
    EXPECT_EQ(ipv6->mqtt->host, "::1");
}

TEST(GatewayConfig, ABadBrokerNamesTheKeyAndTheForm) {
    const std::string device = one_device("device = \"tc10@3\"\n");
    EXPECT_THAT(error_of(device + "[mqtt]\nbroker = \"tcp://127.0.0.1:1883\"\n"),
                StartsWith("plant.toml:9: mqtt.broker: \"tcp://127.0.0.1:1883\" is not a broker address (expected mqtt://"));
    EXPECT_THAT(error_of(device + "[mqtt]\nbroker = \"mqtt://127.0.0.1:99999\"\n"), HasSubstr("is not a broker address"));
    EXPECT_THAT(error_of(device + "[mqtt]\nbroker = \"mqtt://\"\n"), HasSubstr("is not a broker address"));
    EXPECT_THAT(error_of(device + "[mqtt]\nprefix = \"a\"\n"), StartsWith("plant.toml:8: mqtt: missing `broker`"));
}

TEST(GatewayConfig, TheMqttPayloadLimitIsReadAndRangeChecked) {
    const std::string device = one_device("device = \"tc10@3\"\n") + "[mqtt]\nbroker = \"mqtt://127.0.0.1\"\n";
    auto config = parse(device + "max_payload = 4096\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->mqtt->max_payload, 4096u);
    EXPECT_THAT(error_of(device + "max_payload = 8\n"),
                StartsWith("plant.toml:10: mqtt.max_payload: 8 is out of range (expected an integer 16..65536)"));
    EXPECT_THAT(error_of(device + "max_payload = \"1k\"\n"), StartsWith("plant.toml:10: mqtt.max_payload: expected an integer"));
}

TEST(GatewayConfig, ABadMqttPrefixOrAnUnknownMqttKeyIsRefused) {
    const std::string device = one_device("device = \"tc10@3\"\n") + "[mqtt]\nbroker = \"mqtt://127.0.0.1\"\n";
    EXPECT_THAT(error_of(device + "prefix = \"plant/#\"\n"), StartsWith("plant.toml:10: mqtt.prefix: \"plant/#\" is not a topic prefix"));
    EXPECT_THAT(error_of(device + "prefix = \"plant//a\"\n"), HasSubstr("is not a topic prefix"));
    EXPECT_THAT(error_of(device + "prefix = \"/plant\"\n"), HasSubstr("is not a topic prefix"));
    // Spaces, and the broker's own "$" topics, which a subscriber to '#' never sees.
    EXPECT_THAT(error_of(device + "prefix = \"plant one\"\n"), HasSubstr("without '+', '#' or spaces"));
    EXPECT_THAT(error_of(device + "prefix = \"$SYS/loopwire\"\n"), HasSubstr("not starting with '$'"));
    EXPECT_THAT(error_of(device + "prefix = \"plant\\ttab\"\n"), HasSubstr("is not a topic prefix"));
    EXPECT_THAT(error_of(device + "writes = \"yes\"\n"), StartsWith("plant.toml:10: mqtt.writes: expected true or false"));
    EXPECT_THAT(error_of(device + "qos = 2\n"), StartsWith("plant.toml:10: mqtt.qos: unknown key (allowed here: broker, prefix, writes, client_id, ca_file, "
                           "cert_file, key_file, username, password_file, republish, discovery, discovery_prefix, "
                           "max_payload)"));
    EXPECT_THAT(error_of("mqtt = 1\n" + one_device("device = \"tc10@3\"\n")), HasSubstr("expected an [mqtt] table"));
}

// ---------------------------------------------------------------------------------------------
// [sparkplug]

TEST(GatewayConfig, SparkplugSettingsAreRead) {
    auto config = parse("[gateway]\nname = \"plant1\"\n" + one_device("device = \"tc10@3\"\n") +
                        "[sparkplug]\nbroker = \"mqtt://127.0.0.1:1884\"\ngroup_id = \"plant\"\nprimary_host = \"scada\"\n"
                        "writes = true\n");
    ASSERT_TRUE(config) << config.error().message;
    ASSERT_TRUE(config->sparkplug);
    EXPECT_EQ(config->sparkplug->host, "127.0.0.1");
    EXPECT_EQ(config->sparkplug->port, 1884);
    EXPECT_EQ(config->sparkplug->group_id, "plant");
    EXPECT_EQ(config->sparkplug->edge_node_id, "plant1");  // the gateway's name
    EXPECT_EQ(config->sparkplug->primary_host, "scada");
    EXPECT_TRUE(config->sparkplug->writes);
    EXPECT_EQ(config->sparkplug->client_id, "loopwire-sparkplug-plant-plant1");
    EXPECT_FALSE(config->mqtt);  // instead of [mqtt], not beside it
    EXPECT_THAT(describe_plan(*config), HasSubstr("Sparkplug B: mqtt://127.0.0.1:1884 as edge node spBv1.0/plant/.../plant1, "
                                                  "births once host scada is online, DCMD writes allowed"));
}

TEST(GatewayConfig, SparkplugDefaultsAndRefusals) {
    const std::string device = one_device("device = \"tc10@3\"\n");
    auto config = parse(device + "[sparkplug]\nbroker = \"mqtt://broker.local\"\ngroup_id = \"g1\"\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->sparkplug->edge_node_id, "loopwire");  // no [gateway] name
    EXPECT_FALSE(config->sparkplug->writes);               // writes are opt-in
    EXPECT_EQ(config->sparkplug->primary_host, "");
    EXPECT_THAT(error_of(device + "[sparkplug]\nbroker = \"mqtt://broker.local\"\n"),
                StartsWith("plant.toml:8: sparkplug: missing `group_id` (e.g. group_id = \"plant1\")"));
    // A topic level: '/', '+', '#' would break the namespace (Sparkplug 3.0, 4.1).
    EXPECT_THAT(error_of(device + "[sparkplug]\nbroker = \"mqtt://b\"\ngroup_id = \"plant/1\"\n"),
                StartsWith("plant.toml:10: sparkplug.group_id: \"plant/1\" is not a Sparkplug id"));
    EXPECT_THAT(error_of(device + "[sparkplug]\nbroker = \"mqtt://b\"\ngroup_id = \"g\"\nedge_node_id = \"#\"\n"),
                HasSubstr("sparkplug.edge_node_id: \"#\" is not a Sparkplug id"));
    EXPECT_THAT(error_of(device + "[sparkplug]\nbroker = \"tcp://b\"\ngroup_id = \"g\"\n"),
                StartsWith("plant.toml:9: sparkplug.broker: \"tcp://b\" is not a broker address"));
    EXPECT_THAT(error_of(device + "[sparkplug]\nbroker = \"mqtt://b\"\ngroup_id = \"g\"\nca_file = \"x\"\n"),
                HasSubstr("sparkplug.ca_file: "));
    EXPECT_THAT(error_of(device + "[sparkplug]\nbroker = \"mqtt://b\"\ngroup_id = \"g\"\nprefix = \"x\"\n"),
                StartsWith("plant.toml:11: sparkplug.prefix: unknown key (allowed here: broker, group_id, edge_node_id, "
                           "primary_host, state_file, store_and_forward, writes, client_id, ca_file, cert_file, key_file, "
                           "username, password_file)"));
}

TEST(GatewayConfig, SparkplugStoreAndForwardIsADurationOrOff) {
    const std::string head = one_device("device = \"tc10@3\"\n") + "[sparkplug]\nbroker = \"mqtt://b\"\ngroup_id = \"g\"\n";
    auto config = parse(head);
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_FALSE(config->sparkplug->store_and_forward);  // off unless asked for
    config = parse(head + "store_and_forward = \"10m\"\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->sparkplug->store_and_forward, std::chrono::minutes(10));
    EXPECT_THAT(describe_plan(*config), HasSubstr("store and forward: data kept for 10m while the node is dead"));
    // No [history] here: in memory only, and --check says so.
    EXPECT_THAT(describe_plan(*config), HasSubstr("note: store and forward keeps its data in memory only (no [history])"));
    config = parse(head + "store_and_forward = \"off\"\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_FALSE(config->sparkplug->store_and_forward);
    // Refused where it is written, with what is taken.
    EXPECT_THAT(error_of(head + "store_and_forward = \"10 minutes\"\n"), StartsWith("plant.toml:11: sparkplug.store_and_forward: "));
    EXPECT_THAT(error_of(head + "store_and_forward = \"500ms\"\n"),
                StartsWith("plant.toml:11: sparkplug.store_and_forward: expected 1s..24h, or \"off\""));
    EXPECT_THAT(error_of(head + "store_and_forward = 600\n"), StartsWith("plant.toml:11: sparkplug.store_and_forward: "));
}

// ---------------------------------------------------------------------------------------------
// [history]

TEST(GatewayConfig, WithoutAHistoryTableThereIsNoHistory) {
    auto config = parse(one_device("device = \"tc10@3\"\n"));
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_FALSE(config->history);
}

TEST(GatewayConfig, HistorySettingsAreRead) {
    auto config = parse_gateway_config(one_device("device = \"tc10@3\"\n") +
                                           "[history]\ndatabase = \"data/plant.db\"\nkeep = \"30d\"\nheartbeat = \"10s\"\n",
                                       "/etc/loopwire/plant.toml", profiles());
    ASSERT_TRUE(config) << config.error().message;
    ASSERT_TRUE(config->history);
    EXPECT_EQ(config->history->database_as_written, "data/plant.db");
    // Relative to the configuration file's folder, not to where the gateway was started.
    EXPECT_EQ(config->history->database, std::filesystem::path("/etc/loopwire/data/plant.db"));
    EXPECT_EQ(config->history->keep, std::chrono::hours(24 * 30));
    EXPECT_EQ(config->history->heartbeat, std::chrono::seconds(10));
    EXPECT_THAT(describe_plan(*config),
                HasSubstr("history: /etc/loopwire/data/plant.db (SQLite, WAL mode), every change and a heartbeat each 10s, kept 30d"));
}

TEST(GatewayConfig, HistoryDefaultsApplyToWhatIsLeftOut) {
    auto config = parse(one_device("device = \"tc10@3\"\n") + "[history]\ndatabase = \"/var/lib/loopwire/plant.db\"\n");
    ASSERT_TRUE(config) << config.error().message;
    ASSERT_TRUE(config->history);
    EXPECT_EQ(config->history->database, std::filesystem::path("/var/lib/loopwire/plant.db"));  // absolute: as written
    EXPECT_EQ(config->history->keep, std::chrono::hours(24 * 90));
    EXPECT_EQ(config->history->heartbeat, std::chrono::seconds(60));
    EXPECT_THAT(describe_plan(*config), HasSubstr("a heartbeat each 1m, kept 90d"));
    // "~" is a shell's, not a path's: it stays a folder named "~" beside the file.
    auto tilde = parse(one_device("device = \"tc10@3\"\n") + "[history]\ndatabase = \"~/plant.db\"\n");
    ASSERT_TRUE(tilde) << tilde.error().message;
    EXPECT_EQ(tilde->history->database, std::filesystem::path("~/plant.db"));
}

TEST(GatewayConfig, BadHistorySettingsAreRefusedWithTheKey) {
    const std::string device = one_device("device = \"tc10@3\"\n") + "[history]\n";
    EXPECT_THAT(error_of(device + "keep = \"90d\"\n"), StartsWith("plant.toml:8: history: missing `database` (e.g. database = \"plant.db\")"));
    EXPECT_THAT(error_of(device + "database = \"\"\n"), StartsWith("plant.toml:9: history.database: expected the database file's path"));
    EXPECT_THAT(error_of(device + "database = 5\n"), StartsWith("plant.toml:9: history.database: expected a string such as \"plant.db\""));
    const std::string with_file = device + "database = \"plant.db\"\n";
    EXPECT_EQ(error_of(with_file + "keep = \"90 days\"\n"),
              "plant.toml:10: history.keep: '90 days' is not a period: write it like 90d, 12h, 30m or 3600s");
    EXPECT_THAT(error_of(with_file + "keep = \"30s\"\n"), StartsWith("plant.toml:10: history.keep: \"30s\" is too short: keep at least 1m"));
    EXPECT_THAT(error_of(with_file + "keep = 90\n"), StartsWith("plant.toml:10: history.keep: expected a period string such as \"90d\""));
    EXPECT_THAT(error_of(with_file + "heartbeat = \"500ms\"\n"), StartsWith("plant.toml:10: history.heartbeat: expected at least 1s"));
    EXPECT_THAT(error_of(with_file + "heartbeat = \"2d\"\n"), StartsWith("plant.toml:10: history.heartbeat: '2d' is not a duration"));
    EXPECT_THAT(error_of(with_file + "path = \"x\"\n"),
                StartsWith("plant.toml:10: history.path: unknown key (allowed here: database, keep, heartbeat, forward_to, "
                           "password_file)"));
    EXPECT_THAT(error_of("history = 1\n" + one_device("device = \"tc10@3\"\n")), HasSubstr("expected a [history] table"));
}

// [http]

// A token file in its own temporary directory, with the permissions given.
class TokenFile {
public:
    TokenFile(const std::string& content, fs::perms perms) {
        std::string pattern = (fs::temp_directory_path() / "loopwire-token-XXXXXX").string();
        if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp");
        directory_ = pattern;
        std::ofstream(path()) << content;
        fs::permissions(path(), perms);
    }
    ~TokenFile() {
        std::error_code ignored;
        fs::remove_all(directory_, ignored);
    }
    std::string path() const { return (directory_ / "token").string(); }

private:
    fs::path directory_;
};

constexpr auto owner_only = fs::perms::owner_read | fs::perms::owner_write;

TEST(GatewayConfig, WithoutAnHttpTableThereIsNoHttp) {
    auto config = parse(one_device("device = \"tc10@3\"\n"));
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_FALSE(config->http);
}

TEST(GatewayConfig, HttpDefaultsAreLoopbackPort8080AndNoWrites) {
    auto config = parse(one_device("device = \"tc10@3\"\n") + "[http]\n");
    ASSERT_TRUE(config) << config.error().message;
    ASSERT_TRUE(config->http);
    EXPECT_EQ(config->http->host, "127.0.0.1");
    EXPECT_EQ(config->http->port, 8080);
    EXPECT_TRUE(config->http->loopback());
    EXPECT_TRUE(config->http->token.empty());
    EXPECT_EQ(config->http->read_timeout, std::chrono::seconds(10));
    EXPECT_EQ(config->http->send_timeout, std::chrono::seconds(10));
    EXPECT_EQ(config->http->max_connections, 64u);
    EXPECT_EQ(config->http->max_connections_per_client, 8u);
    EXPECT_TRUE(config->http->hosts.empty());
    EXPECT_THAT(describe_plan(*config),
                HasSubstr("HTTP API and dashboard: http://127.0.0.1:8080/, reads open on loopback, writes refused (no http.token_file)"));
}

TEST(GatewayConfig, HttpSettingsAndTheTokenAreRead) {
    TokenFile token("s3cret-token-value\n", owner_only);
    auto config = parse(one_device("device = \"tc10@3\"\n") +
                        fmt::format("[http]\nlisten = \"0.0.0.0:0\"\ntoken_file = \"{}\"\nread_timeout = \"2s\"\n"
                                    "max_connections = 8\nmax_connections_per_client = 3\nsend_timeout = \"30s\"\n"
                                    "hosts = [\"Gateway.Plant.local\", \"192.168.1.10\", \"[FD00::10]\"]\n", token.path()));
    ASSERT_TRUE(config) << config.error().message;
    ASSERT_TRUE(config->http);
    EXPECT_EQ(config->http->host, "0.0.0.0");
    EXPECT_EQ(config->http->port, 0);
    EXPECT_FALSE(config->http->loopback());
    EXPECT_EQ(config->http->token, "s3cret-token-value");
    EXPECT_EQ(config->http->token_file, token.path());
    EXPECT_EQ(config->http->read_timeout, std::chrono::seconds(2));
    EXPECT_EQ(config->http->max_connections, 8u);
    EXPECT_EQ(config->http->max_connections_per_client, 3u);
    EXPECT_EQ(config->http->send_timeout, std::chrono::seconds(30));
    EXPECT_EQ(config->http->hosts, (std::vector<std::string>{"gateway.plant.local", "192.168.1.10", "[fd00::10]"}));
    EXPECT_THAT(describe_plan(*config), HasSubstr(fmt::format("reads need the token, writes need the token in {}", token.path())));
}

// Home Assistant links each device to the dashboard (configuration_url) when [http] serves one:
// at its listen address, or the machine's name for a wildcard one, which a browser elsewhere
// can reach; none without [http], or on port 0 (known only once it listens).
TEST(GatewayConfig, TheDashboardsAddressIsHomeAssistantsConfigurationUrl) {
    const std::string mqtt = "[mqtt]\nbroker = \"mqtt://127.0.0.1\"\ndiscovery = \"homeassistant\"\n";
    TokenFile token("s3cret-token-value\n", owner_only);  // for a listen address that is not loopback
    const auto with_http = [&](const std::string& listen) {
        auto config = parse(one_device("device = \"tc10@3\"\n") + mqtt +
                            fmt::format("[http]\nlisten = \"{}\"\ntoken_file = \"{}\"\n", listen, token.path()));
        EXPECT_TRUE(config) << config.error().message;
        return config ? config->mqtt->configuration_url : std::string("(refused)");
    };
    EXPECT_EQ(with_http("127.0.0.1:8080"), "http://127.0.0.1:8080/");
    EXPECT_EQ(with_http("[::1]:8080"), "http://[::1]:8080/");
    EXPECT_EQ(with_http("127.0.0.1:0"), "");
    std::array<char, 256> host{};
    ASSERT_EQ(::gethostname(host.data(), host.size() - 1), 0);
    EXPECT_EQ(with_http("0.0.0.0:8080"), fmt::format("http://{}:8080/", host.data()));
    auto without = parse(one_device("device = \"tc10@3\"\n") + mqtt);
    ASSERT_TRUE(without) << without.error().message;
    EXPECT_EQ(without->mqtt->configuration_url, "");
}

TEST(GatewayConfig, ABadTokenFileNamesTheKeyAndSaysWhatToDo) {
    const std::string device = one_device("device = \"tc10@3\"\n");
    const auto with_file = [&](const std::string& file) {
        return device + fmt::format("[http]\nlisten = \"127.0.0.1:0\"\ntoken_file = \"{}\"\n", file);
    };
    EXPECT_THAT(error_of(with_file("/nonexistent/token")),
                StartsWith("plant.toml:10: http.token_file: cannot read \"/nonexistent/token\": No such file or directory"));
    TokenFile readable("s3cret-token-value\n", owner_only | fs::perms::group_read | fs::perms::others_read);
    EXPECT_THAT(error_of(with_file(readable.path())),
                AllOf(StartsWith("plant.toml:10: http.token_file:"), HasSubstr("readable by every user (mode 0644)"),
                      HasSubstr("chmod 600")));
    TokenFile empty("\n", owner_only);
    EXPECT_THAT(error_of(with_file(empty.path())), HasSubstr("is empty"));
    TokenFile spaces("two words\n", owner_only);
    EXPECT_THAT(error_of(with_file(spaces.path())), HasSubstr("without spaces"));
}

TEST(GatewayConfig, ListeningBeyondLoopbackNeedsAToken) {
    EXPECT_THAT(error_of(one_device("device = \"tc10@3\"\n") + "[http]\nlisten = \"0.0.0.0:8080\"\n"),
                AllOf(StartsWith("plant.toml:9: http.listen: \"0.0.0.0\" is not a loopback address"), HasSubstr("http.token_file")));
}

TEST(GatewayConfig, BadHttpSettingsSayWhatIsExpected) {
    const std::string device = one_device("device = \"tc10@3\"\n") + "[http]\n";
    EXPECT_THAT(error_of(device + "listen = \"8080\"\n"), StartsWith("plant.toml:9: http.listen: \"8080\" is not an address"));
    EXPECT_THAT(error_of(device + "read_timeout = \"1ms\"\n"), StartsWith("plant.toml:9: http.read_timeout: expected 100ms..10min"));
    EXPECT_THAT(error_of(device + "max_connections = 0\n"), StartsWith("plant.toml:9: http.max_connections: 0 is out of range"));
    EXPECT_THAT(error_of(device + "send_timeout = \"20min\"\n"), StartsWith("plant.toml:9: http.send_timeout: expected 100ms..10min"));
    EXPECT_THAT(error_of(device + "max_connections_per_client = 0\n"),
                StartsWith("plant.toml:9: http.max_connections_per_client: 0 is out of range"));
    EXPECT_THAT(error_of(device + "hosts = \"gateway.local\"\n"), StartsWith("plant.toml:9: http.hosts: expected a list of host names"));
    EXPECT_THAT(error_of(device + "hosts = [\"gateway.local:8080\"]\n"),
                AllOf(StartsWith("plant.toml:9: http.hosts[0]: \"gateway.local:8080\" is not a host name"),
                      HasSubstr("without a port or scheme")));
    EXPECT_THAT(error_of(device + "hosts = [\"http://gateway.local\"]\n"), HasSubstr("is not a host name"));
    EXPECT_THAT(error_of(device + "hosts = [\"a\\u001b[2Jb\"]\n"), HasSubstr("\"a\\x1b[2Jb\" is not a host name"));
    EXPECT_THAT(error_of(device + "hosts = [3]\n"), StartsWith("plant.toml:9: http.hosts[0]: expected a host name (a string)"));
    EXPECT_THAT(error_of(device + "token = \"abc\"\n"), HasSubstr("http.token: unknown key (allowed here: listen, token_file"));
    EXPECT_THAT(error_of("http = 1\n" + one_device("device = \"tc10@3\"\n")), HasSubstr("expected an [http] table"));
}

// Event streams may hold only a share of the connections: half of each limit unless given, and
// always fewer, so that requests find one however many dashboards are open.
TEST(GatewayConfig, TheEventStreamsShareAndTheHeaderTimeoutAreRead) {
    const std::string device = one_device("device = \"tc10@3\"\n") + "[http]\n";
    auto halves = parse(device + "max_connections = 10\nmax_connections_per_client = 5\n");
    ASSERT_TRUE(halves) << halves.error().message;
    EXPECT_EQ(halves->http->max_event_streams, 5u);
    EXPECT_EQ(halves->http->max_event_streams_per_client, 2u);
    EXPECT_EQ(halves->http->header_timeout, std::chrono::seconds(5));
    auto given = parse(device + "max_event_streams = 60\nmax_event_streams_per_client = 7\nheader_timeout = \"2s\"\n");
    ASSERT_TRUE(given) << given.error().message;
    EXPECT_EQ(given->http->max_event_streams, 60u);
    EXPECT_EQ(given->http->max_event_streams_per_client, 7u);
    EXPECT_EQ(given->http->header_timeout, std::chrono::seconds(2));
    EXPECT_THAT(error_of(device + "max_event_streams = 64\n"),
                StartsWith("plant.toml:9: http.max_event_streams: 64 event streams leave no connection of [http] "
                           "max_connections (64) for requests: make it at most 63"));
    EXPECT_THAT(error_of(device + "max_connections_per_client = 4\nmax_event_streams_per_client = 4\n"),
                StartsWith("plant.toml:10: http.max_event_streams_per_client: 4 event streams leave no connection of [http] "
                           "max_connections_per_client (4) for requests: make it at most 3"));
    EXPECT_THAT(error_of(device + "header_timeout = \"50ms\"\n"), StartsWith("plant.toml:9: http.header_timeout: expected 100ms..10min"));
}

TEST(GatewayConfig, TheGatewayNameGivesTheMqttPrefixAndDiscoveryName) {
    const std::string device = one_device("device = \"tc10@3\"\n");
    auto named = parse("[gateway]\nname = \"plant-2\"\n" + device + "[mqtt]\nbroker = \"mqtt://127.0.0.1\"\n");
    ASSERT_TRUE(named) << named.error().message;
    EXPECT_EQ(named->name, "plant-2");
    EXPECT_EQ(named->mqtt->prefix, "loopwire/plant-2");
    EXPECT_EQ(named->mqtt->gateway_name, "plant-2");
    // Without a name, the prefix's last level, made safe for object ids.
    auto unnamed = parse(device + "[mqtt]\nbroker = \"mqtt://127.0.0.1\"\nprefix = \"site-a/gw.1~x\"\n");
    ASSERT_TRUE(unnamed) << unnamed.error().message;
    EXPECT_EQ(unnamed->mqtt->gateway_name, "gw_1_x");
    EXPECT_THAT(error_of("[gateway]\nname = \"my plant\"\n" + device), StartsWith("plant.toml:2: gateway.name: \"my plant\" is not a valid name"));
    // A misspelt key is unknown, and the key meant is missing: both are said.
    EXPECT_EQ(error_of("[gateway]\nnom = \"x\"\n" + device),
              "plant.toml:1: gateway: missing `name` (e.g. name = \"furnace-line\")\n"
              "plant.toml:2: gateway.nom: unknown key (allowed here: name)\n"
              "2 mistakes in plant.toml");
}

TEST(GatewayConfig, MqttPublishingSettingsAreRead) {
    const std::string device = one_device("device = \"tc10@3\"\n") + "[mqtt]\nbroker = \"mqtt://127.0.0.1\"\n";
    auto config = parse(device + "republish = \"30s\"\ndiscovery = \"homeassistant\"\ndiscovery_prefix = \"ha\"\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->mqtt->republish, std::chrono::seconds(30));
    EXPECT_EQ(config->mqtt->discovery, MqttConfig::Discovery::homeassistant);
    EXPECT_EQ(config->mqtt->discovery_prefix, "ha");
    auto off = parse(device + "republish = \"off\"\n");
    ASSERT_TRUE(off) << off.error().message;
    EXPECT_FALSE(off->mqtt->republish);
    EXPECT_THAT(error_of(device + "republish = \"10ms\"\n"), StartsWith("plant.toml:10: mqtt.republish: expected at least 100ms"));
    EXPECT_THAT(error_of(device + "republish = \"often\"\n"), StartsWith("plant.toml:10: mqtt.republish: "));
    EXPECT_THAT(error_of(device + "discovery = \"openhab\"\n"),
                StartsWith("plant.toml:10: mqtt.discovery: \"openhab\" is not a discovery scheme"));
    EXPECT_THAT(error_of(device + "discovery_prefix = \"home assistant\"\n"),
                StartsWith("plant.toml:10: mqtt.discovery_prefix: \"home assistant\" is not a topic prefix"));
}

// Files beside a configuration that is a file: its folder is where relative names are found.
class MqttFiles : public ::testing::Test {
protected:
    void SetUp() override {
        std::string pattern = (std::filesystem::temp_directory_path() / "loopwire-config-XXXXXX").string();
        ASSERT_TRUE(::mkdtemp(pattern.data()));
        directory_ = pattern;
    }
    void TearDown() override {
        std::error_code ignored;
        std::filesystem::remove_all(directory_, ignored);
    }
    void write(const std::string& name, const std::string& text, std::filesystem::perms perms) {
        std::ofstream(directory_ / name) << text;
        std::filesystem::permissions(directory_ / name, perms);
    }
    Result<GatewayConfig> parse_here(const std::string& mqtt) {
        return parse_gateway_config(one_device("device = \"tc10@3\"\n") + "[mqtt]\n" + mqtt, (directory_ / "plant.toml").string(),
                                    profiles());
    }
    std::string error_here(const std::string& mqtt) {
        auto config = parse_here(mqtt);
        return config ? std::string("(no error)") : config.error().message;
    }
    std::filesystem::path directory_;
};


TEST_F(MqttFiles, TlsAndAPasswordFromAFileAreRead) {
    write("ca.crt", "certificate", owner_only | std::filesystem::perms::others_read);
    write("secret", "s3cret\n", owner_only);
    auto config = parse_here("broker = \"mqtts://broker.local\"\nca_file = \"ca.crt\"\nusername = \"gw\"\npassword_file = \"secret\"\n");
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->mqtt->port, 8883);  // MQTT over TLS's port
    ASSERT_TRUE(config->mqtt->tls);
    EXPECT_EQ(config->mqtt->tls->ca_file, directory_ / "ca.crt");
    EXPECT_EQ(config->mqtt->username, "gw");
    EXPECT_EQ(config->mqtt->password, "s3cret");  // without the newline
}

TEST_F(MqttFiles, ABadPasswordFileOrTlsFileIsNamed) {
    write("open", "s3cret\n", owner_only | std::filesystem::perms::others_read);
    write("empty", "", owner_only);
    write("ca.crt", "certificate", owner_only);
    const std::string plain = "broker = \"mqtt://127.0.0.1\"\nusername = \"gw\"\n";
    EXPECT_THAT(error_here(plain + "password_file = \"missing\"\n"),
                AllOf(HasSubstr("mqtt.password_file: "), HasSubstr("missing\" does not exist (expected a file whose first line")));
    EXPECT_THAT(error_here(plain + "password_file = \"open\"\n"),
                AllOf(HasSubstr("mqtt.password_file: "), HasSubstr("is readable by every user; make it private (chmod 600")));
    EXPECT_THAT(error_here(plain + "password_file = \"empty\"\n"), HasSubstr("mqtt.password_file: "));
    EXPECT_THAT(error_here(plain + "password = \"inline\"\n"), HasSubstr("mqtt.password: unknown key"));
    EXPECT_THAT(error_here("broker = \"mqtt://127.0.0.1\"\nca_file = \"ca.crt\"\n"), HasSubstr("mqtt.ca_file: only used over TLS"));
    EXPECT_THAT(error_here("broker = \"mqtts://127.0.0.1\"\nca_file = \"nope.crt\"\n"),
                AllOf(HasSubstr("mqtt.ca_file: "), HasSubstr("nope.crt\" does not exist")));
    EXPECT_THAT(error_here("broker = \"mqtts://127.0.0.1\"\ncert_file = \"ca.crt\"\n"),
                HasSubstr("cert_file and key_file go together: `key_file` is missing"));
}

// ---- files that are not regular files ----------------------------------------------------
//
// A FIFO named where a file is expected must be refused before it is opened: opening it for
// reading would wait for a writer, hanging `--check`, or a reload on the thread that also
// takes SIGTERM. These tests would hang, not fail, if a FIFO were opened: ctest's timeout ends
// them.

class FifoInTheConfiguration : public MqttFiles {
protected:
    std::string fifo(const std::string& name) {
        const auto path = directory_ / name;
        EXPECT_EQ(::mkfifo(path.c_str(), 0600), 0) << std::strerror(errno);
        return path.string();
    }
    std::string error_with(const std::string& tables) {
        auto config = parse_gateway_config(one_device("device = \"tc10@3\"\n") + tables, (directory_ / "plant.toml").string(),
                                           profiles());
        return config ? std::string("(no error)") : config.error().message;
    }
};

TEST_F(FifoInTheConfiguration, AsPasswordOrTlsFileItIsRefusedWithTheKey) {
    fifo("secret");
    fifo("ca.crt");
    write("real.crt", "certificate", owner_only);
    const std::string password = error_here("broker = \"mqtt://127.0.0.1\"\nusername = \"gw\"\npassword_file = \"secret\"\n");
    EXPECT_THAT(password, AllOf(HasSubstr("plant.toml:11: mqtt.password_file: "),
                                HasSubstr("secret\" is a FIFO (named pipe), not a regular file"),
                                HasSubstr("name a regular file")))
        << password;
    const std::string ca = error_here("broker = \"mqtts://127.0.0.1\"\nca_file = \"ca.crt\"\n");
    EXPECT_THAT(ca, AllOf(HasSubstr("plant.toml:10: mqtt.ca_file: "), HasSubstr("is a FIFO (named pipe), not a regular file"),
                          HasSubstr("the broker's CA certificate")))
        << ca;
    fifo("client.key");
    const std::string key = error_here("broker = \"mqtts://127.0.0.1\"\ncert_file = \"real.crt\"\nkey_file = \"client.key\"\n");
    EXPECT_THAT(key, HasSubstr("mqtt.key_file: ")) << key;
    EXPECT_THAT(key, HasSubstr("is a FIFO")) << key;
    const std::string directory = error_here("broker = \"mqtts://127.0.0.1\"\nca_file = \".\"\n");
    EXPECT_THAT(directory, HasSubstr("is a directory, not a regular file")) << directory;
}

TEST_F(FifoInTheConfiguration, AsTokenFileOrHistoryDatabaseItIsRefusedWithTheKey) {
    const std::string token = fifo("token");
    const std::string http = error_with(fmt::format("[http]\nlisten = \"127.0.0.1:0\"\ntoken_file = \"{}\"\n", token));
    EXPECT_THAT(http, AllOf(HasSubstr("http.token_file: "), HasSubstr("is a FIFO (named pipe), not a regular file"))) << http;
    fifo("plant.db");
    const std::string history = error_with("[history]\ndatabase = \"plant.db\"\n");
    EXPECT_THAT(history, AllOf(HasSubstr("plant.toml:9: history.database: "), HasSubstr("is a FIFO (named pipe)"),
                               HasSubstr("created when absent")))
        << history;
    // Absent, it is simply created when the gateway opens.
    const std::string absent = error_with("[history]\ndatabase = \"new.db\"\n");
    EXPECT_EQ(absent, "(no error)");
    const std::string character_device = error_with("[history]\ndatabase = \"/dev/null\"\n");
    EXPECT_THAT(character_device, HasSubstr("\"/dev/null\" is a character device, not a regular file")) << character_device;
}

TEST_F(FifoInTheConfiguration, AsTheConfigurationItselfItIsRefused) {
    const std::string config = fifo("gateway.toml");
    auto loaded = load_gateway_config(config, profiles());
    ASSERT_FALSE(loaded);
    EXPECT_THAT(loaded.error().message,
                AllOf(HasSubstr("cannot read the gateway configuration"), HasSubstr("is a FIFO (named pipe), not a regular file")));
}

// [history] forward_to: the three forms libpq reads, a name required, and the password file.

std::string forwarded(const std::string& keys) {
    return "[gateway]\nname = \"plant1\"\n" + one_device("device = \"tc10@3\"\n") +
           "[history]\ndatabase = \"plant.db\"\n" + keys;
}

TEST(GatewayConfig, HistoryForwardToTakesEveryFormOfConnectionString) {
    for (const std::string target : {"postgresql://gateway@historian:5432/plant", "host=/var/run/postgresql dbname=plant",
                                     "postgresql:///plant?host=/tmp/x", "postgresql://gw@historian/plant?sslmode=verify-full"}) {
        auto config = parse(forwarded("forward_to = \"" + target + "\"\n"));
        ASSERT_TRUE(config) << target << ": " << config.error().message;
        EXPECT_EQ(config->history->forward_to, target);
        EXPECT_EQ(config->history->database.filename(), "plant.db");  // still the local file
    }
    auto plain = parse(forwarded(""));
    ASSERT_TRUE(plain) << plain.error().message;
    EXPECT_TRUE(plain->history->forward_to.empty());
}

TEST(GatewayConfig, BadHistoryForwardingIsRefusedWithTheKey) {
    EXPECT_THAT(error_of(forwarded("forward_to = \"historian:5432\"\n")),
                HasSubstr("history.forward_to: \"historian:5432\" is not a PostgreSQL connection string"));
    EXPECT_THAT(error_of(forwarded("forward_to = \"postgresql://h/plant?nonsense=1\"\n")),
                HasSubstr("history.forward_to: libpq cannot read it: invalid URI query parameter"));
    EXPECT_THAT(error_of(forwarded("forward_to = \"host=/tmp dbname\"\n")), HasSubstr("history.forward_to: libpq cannot read it"));
    // The historian named as the local file: told where it goes instead.
    EXPECT_THAT(error_of(one_device("device = \"tc10@3\"\n") + "[history]\ndatabase = \"postgresql://gw@historian/plant\"\n"),
                HasSubstr("history.database: \"postgresql://gw@historian/plant\" is a PostgreSQL connection string; "
                          "database is the gateway's own SQLite file, which buffers what is forwarded: write database = "
                          "\"plant.db\" and forward_to = \"postgresql://gw@historian/plant\""));
    EXPECT_THAT(error_of(one_device("device = \"tc10@3\"\n") + "[history]\ndatabase = \"host=/run/postgresql dbname=plant\"\n"),
                HasSubstr("is a PostgreSQL connection string"));
    // Without [gateway] name the shared historian could not tell this gateway's series apart.
    EXPECT_THAT(error_of(one_device("device = \"tc10@3\"\n") +
                         "[history]\ndatabase = \"plant.db\"\nforward_to = \"postgresql:///plant\"\n"),
                HasSubstr("history.forward_to: needs [gateway] name"));
}

TEST(GatewayConfig, HistoryPasswordFileIsReadAndMustBePrivate) {
    TokenFile secret("s3cret\n", fs::perms::owner_read | fs::perms::owner_write);
    auto config = parse(forwarded("forward_to = \"postgresql://gw@historian/plant\"\npassword_file = \"" + secret.path() + "\"\n"));
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->history->password, "s3cret");
    TokenFile open_secret("s3cret\n", fs::perms::owner_read | fs::perms::owner_write | fs::perms::others_read);
    EXPECT_THAT(error_of(forwarded("forward_to = \"postgresql://gw@historian/plant\"\npassword_file = \"" +
                                   open_secret.path() + "\"\n")),
                AllOf(HasSubstr("history.password_file: "), HasSubstr("is readable by every user; make it private")));
    EXPECT_THAT(error_of(forwarded("password_file = \"" + secret.path() + "\"\n")),
                HasSubstr("history.password_file: only used with `forward_to`"));
}

}  // namespace
}  // namespace loopwire::gateway

namespace loopwire::gateway {
namespace {

std::string points_device(const std::string& points) {
    return "[[lines]]\nname = \"meters\"\nlink = \"tcp://127.0.0.1:5020\"\n\n"
           "[[lines.devices]]\nname = \"meter1\"\nunit = 7\n" + points;
}

TEST(DevicePoints, PointsBecomeTheDevicesProfile) {
    auto config = parse(points_device(R"(
[[lines.devices.points]]
name = "voltage"
address = "30001"
type = "uint16"
scale = 0.1
unit = "V"
[[lines.devices.points]]
name = "limit"
address = "40011"
type = "int16"
min = -5
max = 100
writable = true
[[lines.devices.points]]
name = "relay"
table = "coil"
address = 3
writable = true
poll = false
)"));
    ASSERT_TRUE(config.ok()) << config.error().message;
    const DeviceConfig& device = config->lines.at(0).devices.at(0);
    EXPECT_EQ(device.address.unit, 7);
    EXPECT_EQ(device.parameters, (std::vector<std::string>{"voltage", "limit"}));
    const device::Parameter* voltage = device.address.profile->find("voltage");
    ASSERT_NE(voltage, nullptr);
    EXPECT_EQ(voltage->table, device::Table::input_registers);
    EXPECT_EQ(voltage->address, 0);
    EXPECT_EQ(std::get<int>(voltage->decimals), 1);
    EXPECT_EQ(voltage->unit, "V");
    const device::Parameter* limit = device.address.profile->find("limit");
    ASSERT_NE(limit, nullptr);
    EXPECT_EQ(limit->table, device::Table::holding_registers);
    EXPECT_EQ(limit->address, 10);
    EXPECT_TRUE(limit->writable);
    const device::Parameter* relay = device.address.profile->find("relay");
    ASSERT_NE(relay, nullptr);
    EXPECT_EQ(relay->table, device::Table::coils);
    EXPECT_EQ(relay->type, device::ValueType::boolean);
}

TEST(DevicePoints, EveryMistakeIsSaidWithItsLine) {
    const std::string message = error_of(points_device(R"(
[[lines.devices.points]]
name = "a"
address = "40001"
type = "float32"
[[lines.devices.points]]
name = "b"
address = 0
table = "holding"
type = "int16"
min = 5
max = 1
[[lines.devices.points]]
name = "c"
address = "30001"
type = "uint16"
writable = true
[[lines.devices.points]]
name = "d"
address = "30001"
table = "holding"
type = "uint16"
[[lines.devices.points]]
name = "e"
address = 2
table = "holding"
type = "int128"
)"));
    EXPECT_THAT(message, HasSubstr("plant.toml:12: lines[0].devices[0].points[0].type: float32 spans more than one register"));
    EXPECT_THAT(message, HasSubstr("plant.toml:18: lines[0].devices[0].points[1].min: min 5 is above max 1"));
    EXPECT_THAT(message, HasSubstr("points[2].writable: the input table is read-only"));
    EXPECT_THAT(message, HasSubstr("points[3].table: the reference is in table input, not holding"));
    EXPECT_THAT(message, HasSubstr("points[4].type: unknown type \"int128\""));
}

TEST(DevicePoints, TwoPointsOnOneRegisterAreRefused) {
    const std::string message = error_of(points_device(R"(
[[lines.devices.points]]
name = "a"
address = "40002"
type = "uint16"
[[lines.devices.points]]
name = "b"
address = 1
table = "holding"
type = "int16"
)"));
    EXPECT_THAT(message, HasSubstr("points[1].address: holding 1 is already point a"));
}

TEST(DevicePoints, AProfileAndPointsTogetherAreRefused) {
    EXPECT_THAT(error_of(points_device("device = \"tc10@1\"\n[[lines.devices.points]]\nname = \"a\"\naddress = 1\n"
                                      "table = \"holding\"\ntype = \"uint16\"\n")),
                HasSubstr("not both"));
}

}  // namespace
}  // namespace loopwire::gateway

namespace loopwire::gateway {
namespace {

// `loopwire profile from-points` writes a profile that loads to the model the gateway gave the device.
TEST(DevicePoints, TheWrittenProfileLoadsToTheSameModel) {
    const std::string text = points_device(R"(
[[lines.devices.points]]
name = "voltage"
address = "30001"
type = "uint16"
decimals = 1
unit = "V"
[[lines.devices.points]]
name = "status"
address = "40012"
type = "bits"
)");
    const fs::path file = fs::temp_directory_path() / fmt::format("points-{}.toml", ::getpid());
    std::ofstream(file) << text;
    auto written = points_profile_text(file, "meter1");
    fs::remove(file);
    ASSERT_TRUE(written.ok()) << written.error().message;
    auto loaded = device::load_profile_text(*written, "meter1.json");
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    auto config = parse(text);
    ASSERT_TRUE(config.ok()) << config.error().message;
    const device::Profile& served = *config->lines.at(0).devices.at(0).address.profile;
    EXPECT_EQ(loaded->id, served.id);
    ASSERT_EQ(loaded->parameters.size(), served.parameters.size());
    for (std::size_t i = 0; i < served.parameters.size(); ++i) {
        EXPECT_EQ(loaded->parameters[i].name, served.parameters[i].name);
        EXPECT_EQ(loaded->parameters[i].table, served.parameters[i].table);
        EXPECT_EQ(loaded->parameters[i].address, served.parameters[i].address);
        EXPECT_EQ(loaded->parameters[i].type, served.parameters[i].type);
        EXPECT_EQ(loaded->parameters[i].unit, served.parameters[i].unit);
        EXPECT_EQ(loaded->parameters[i].decimals, served.parameters[i].decimals);
    }
}

}  // namespace
}  // namespace loopwire::gateway
