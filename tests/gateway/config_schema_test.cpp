// The configuration's schema (gateway/config_schema.hpp) against the parser that uses it: every
// key it describes is read (a value of the wrong type is refused naming the key), no other key
// is taken, and the example `loopwire gateway --print-config` prints parses to the defaults the
// schema states.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

#include "gateway/config_schema.hpp"
#include "gateway/gateway_config.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::gateway {
namespace {

using ::testing::HasSubstr;

Result<GatewayConfig> parse(const std::string& text) {
    return parse_gateway_config(text, "schema.toml", device::testing::builtin_registry());
}

// A valid configuration with every table, each block holding what its table needs; `extra` is
// added to the block of one table.
std::string configuration_with(std::string_view table, const std::string& extra) {
    const std::vector<std::pair<std::string_view, std::string>> blocks{
        {"gateway", "[gateway]\nname = \"plant1\"\n"},
        {"lines", "[[lines]]\nname = \"line1\"\nlink = \"rtu:virtual?baud=19200\"\n"},
        {"lines.devices", "[[lines.devices]]\nname = \"oven\"\ndevice = \"tc10@3\"\n"},
        {"modbus_tcp", "[modbus_tcp]\n"},
        {"log", "[log]\n"},
        {"mqtt", "[mqtt]\nbroker = \"mqtt://127.0.0.1:1883\"\n"},
        {"sparkplug", "[sparkplug]\nbroker = \"mqtt://127.0.0.1:1883\"\ngroup_id = \"plant1\"\n"},
        {"history", "[history]\ndatabase = \"plant.db\"\n"},
        {"http", "[http]\n"},
        {"opcua", "[opcua]\n"},
        {"alarms", "[alarms]\n"},
        {"alarms.limits", "[[alarms.limits]]\ndevice = \"oven\"\nparameter = \"measured_value\"\nkind = \"high\"\nlimit = 250\n"},
    };
    // A device of points: its table's keys go to its one point; its `unit` to the device (one more,
    // of points).
    const std::string point = "[[lines.devices.points]]\nname = \"p\"\naddress = 1\ntable = \"holding\"\ntype = \"uint16\"\n";
    const bool device_unit = table == "lines.devices" && extra.starts_with("unit ");
    std::string text;
    for (const auto& [name, block] : blocks) {
        if (name == "lines.devices" && device_unit) {
            // Beside the oven, which the alarm limit's block watches.
            text += block + "\n[[lines.devices]]\nname = \"pump\"\n" + extra + point + "\n";
            continue;
        }
        text += block + (name == table ? extra : "") + "\n";
        if (name == "lines.devices") {
            text += "[[lines.devices]]\nname = \"meter\"\nunit = 4\n" + point + (table == "lines.devices.points" ? extra : "") + "\n";
        }
    }
    return text;
}

TEST(ConfigSchema, TheConfigurationWithEveryTableParses) {
    auto config = parse(configuration_with("", ""));
    ASSERT_TRUE(config) << config.error().message;
}

TEST(ConfigSchema, EveryKeyItDescribesIsReadByTheParser) {
    // A key the parser never looked at would take any value: an inline table is no key's type.
    for (const ConfigKey& key : config_keys()) {
        const std::string text = configuration_with(key.table, fmt::format("{} = {{ wrong = 1 }}\n", key.key));
        // Required keys are in the blocks already: set twice is a TOML error, not the parser's.
        if (key.required()) continue;
        auto config = parse(text);
        ASSERT_FALSE(config) << key.table << "." << key.key << " took an inline table";
        EXPECT_THAT(config.error().message, HasSubstr(std::string(key.key))) << key.table << "." << key.key;
    }
}

// The numbers an integer or number key takes are the schema's: its words (the man page's
// "Values:") begin with them, and the parser refuses one step outside either end, quoting them.
TEST(ConfigSchema, TheRangesItStatesAreTheOnesEnforced) {
    for (const ConfigKey& key : config_keys()) {
        if (key.type != "integer" && key.type != "number") continue;
        SCOPED_TRACE(fmt::format("{}.{}", key.table, key.key));
        const ConfigRange& range = config_range(key.table, key.key);
        EXPECT_THAT(std::string(key.bounds), ::testing::StartsWith(fmt::format("{}..{}", range.least, range.most)));
        const bool integer = key.type == "integer";
        const double step = integer ? 1.0 : range.least / 2;
        for (const double outside : {range.least - step, range.most + (integer ? 1.0 : range.most)}) {
            const std::string value = integer ? fmt::format("{}", static_cast<long long>(outside)) : fmt::format("{:.6f}", outside);
            auto config = parse(configuration_with(key.table, fmt::format("{} = {}\n", key.key, value)));
            ASSERT_FALSE(config) << value << " was taken";
            EXPECT_THAT(config.error().message,
                        HasSubstr(fmt::format("out of range (expected {} {}..{})", integer ? "an integer" : "a number",
                                              range.least, range.most)));
        }
    }
    EXPECT_THROW(config_range("lines", "name"), std::logic_error) << "a string has no range";
}

// A duration in the words the schema uses: 1ms, 100ms, 1s, 1min, 24h.
std::string duration_words(double ms) {
    const auto whole = static_cast<long long>(ms);
    if (whole % 3'600'000 == 0) return fmt::format("{}h", whole / 3'600'000);
    if (whole % 60'000 == 0) return fmt::format("{}min", whole / 60'000);
    if (whole % 1'000 == 0) return fmt::format("{}s", whole / 1'000);
    return fmt::format("{}ms", whole);
}

// Durations too: the words state the schema's range ("1ms..1min", "at least 1s"), the parser
// refuses a millisecond outside it and quotes those words, never a minimum it does not enforce.
TEST(ConfigSchema, TheDurationRangesItStatesAreTheOnesEnforced) {
    for (const ConfigKey& key : config_keys()) {
        if (key.type != "duration") continue;
        SCOPED_TRACE(fmt::format("{}.{}", key.table, key.key));
        const ConfigRange& range = config_range(key.table, key.key);
        const bool bounded = std::isfinite(range.most);
        const std::string words = bounded ? fmt::format("{}..{}", duration_words(range.least), duration_words(range.most))
                                          : fmt::format("at least {}", duration_words(range.least));
        EXPECT_THAT(std::string(key.bounds), ::testing::StartsWith(words));
        std::vector<double> outside{range.least - 1};
        if (bounded) outside.push_back(range.most + 1);
        for (const double ms : outside) {
            auto config = parse(configuration_with(key.table, fmt::format("{} = \"{}ms\"\n", key.key, static_cast<long long>(ms))));
            ASSERT_FALSE(config) << ms << " ms was taken";
            // Past a day the duration parser itself says so ("give at most 24h"), which is this range's end.
            EXPECT_THAT(config.error().message,
                        ::testing::AnyOf(HasSubstr(words), HasSubstr(fmt::format("at most {}", duration_words(range.most)))))
                << "the refusal quotes the range";
        }
        auto at_least = parse(configuration_with(key.table, fmt::format("{} = \"{}ms\"\n", key.key, static_cast<long long>(range.least))));
        EXPECT_TRUE(at_least) << at_least.error().message;
    }
}

TEST(ConfigSchema, TheRequiredKeysAreRequired) {
    for (const ConfigKey& key : config_keys()) {
        if (!key.required()) continue;
        std::string text = configuration_with("", "");
        // The block's own line for the key goes; the key is then missing.
        const std::string line = fmt::format("\n{} = ", key.key);
        const auto table = std::find_if(config_tables().begin(), config_tables().end(),
                                        [&](const ConfigTable& each) { return each.name == key.table; });
        ASSERT_NE(table, config_tables().end()) << key.table;
        const auto header = text.find(std::string(table->header) + "\n");
        ASSERT_NE(header, std::string::npos) << key.table;
        const auto at = text.find(line, header);
        ASSERT_NE(at, std::string::npos) << key.table << "." << key.key;
        text.erase(at + 1, text.find('\n', at + 1) - at);
        auto config = parse(text);
        ASSERT_FALSE(config) << key.table << "." << key.key << " is said required, yet the file parses without it";
        EXPECT_THAT(config.error().message, HasSubstr(fmt::format("missing `{}`", key.key)));
    }
}

TEST(ConfigSchema, AKeyItDoesNotDescribeIsRefusedNamingTheKeysItDoes) {
    for (const ConfigTable& table : config_tables()) {
        auto config = parse(configuration_with(table.name, "no_such_key = 1\n"));
        ASSERT_FALSE(config) << table.name;
        EXPECT_THAT(config.error().message, HasSubstr("no_such_key: unknown key (allowed here: "));
        for (std::string_view key : config_keys_of(table.name)) {
            EXPECT_THAT(config.error().message, HasSubstr(std::string(key))) << table.name;
        }
    }
    auto top = parse(configuration_with("", "") + "[no_such_table]\n");
    ASSERT_FALSE(top);
    EXPECT_THAT(top.error().message, HasSubstr("allowed here: gateway, lines, modbus_tcp, log, mqtt, sparkplug, history, http"));
}

TEST(ConfigSchema, TablesHoldTheTablesBelowThem) {
    const auto lines = config_keys_of("lines");
    EXPECT_NE(std::find(lines.begin(), lines.end(), "devices"), lines.end());
    const auto devices = config_keys_of("lines.devices");
    EXPECT_EQ(std::find(devices.begin(), devices.end(), "devices"), devices.end());
}

// The printed example writes each default; what it parses to is what the gateway's types
// default to, so the schema's defaults and the parser's cannot drift apart.
TEST(ConfigSchema, ThePrintedExampleParsesToTheDefaults) {
    auto config = parse(commented_example_config());
    ASSERT_TRUE(config) << config.error().message;
    EXPECT_EQ(config->modbus_tcp, ModbusTcpConfig{});
    EXPECT_EQ(config->log, LogConfig{});
    ASSERT_TRUE(config->http);
    HttpConfig http_defaults;
    EXPECT_EQ(*config->http, http_defaults);
    ASSERT_TRUE(config->history);
    EXPECT_EQ(config->history->keep, HistoryConfig{}.keep);
    EXPECT_EQ(config->history->heartbeat, HistoryConfig{}.heartbeat);
    ASSERT_TRUE(config->mqtt);
    const MqttConfig mqtt_defaults;
    EXPECT_EQ(config->mqtt->republish, mqtt_defaults.republish);
    EXPECT_EQ(config->mqtt->writes, mqtt_defaults.writes);
    EXPECT_EQ(config->mqtt->discovery, mqtt_defaults.discovery);
    EXPECT_EQ(config->mqtt->discovery_prefix, mqtt_defaults.discovery_prefix);
    EXPECT_EQ(config->mqtt->max_payload, mqtt_defaults.max_payload);
    EXPECT_EQ(config->mqtt->prefix, "loopwire/" + config->name);  // the default prefix, as the schema says
    ASSERT_EQ(config->lines.size(), 1u);
    const LineConfig& line = config->lines.front();
    const LineConfig line_defaults;
    EXPECT_EQ(line.timeout, line_defaults.timeout);
    EXPECT_EQ(line.retries, line_defaults.retries);
    EXPECT_EQ(line.max_in_flight, line_defaults.max_in_flight);
    EXPECT_FALSE(line.late_reply_window);
    ASSERT_TRUE(line.simulation);
    EXPECT_EQ(*line.simulation, LineSimulation{});
    ASSERT_EQ(line.devices.size(), 1u);
    EXPECT_EQ(line.devices.front().poll, DeviceConfig{}.poll);
    EXPECT_TRUE(line.devices.front().parameters.empty());  // commented out: the profile's watch list
}

// Each commented-out key of the example, uncommented, parses too where it needs nothing more than
// the file (a TLS file must exist, and needs mqtts://): the example values are values the parser takes.
TEST(ConfigSchema, TheExampleValuesOfCommentedKeysAreTaken) {
    for (const ConfigKey& key : config_keys()) {
        if (!key.example_commented || key.type == "file") continue;
        const std::string text = configuration_with(key.table, fmt::format("{} = {}\n", key.key, key.example));
        auto config = parse(text);
        EXPECT_TRUE(config) << key.table << "." << key.key << ": " << (config ? "" : config.error().message);
    }
}

}  // namespace
}  // namespace loopwire::gateway
