// The MQTT front builds a value's /meta document only when what it is made of changed
// (gateway/mqtt_documents.hpp, meta_inputs): a value alone must never be taken for the same
// meta when the document would differ, nor rebuild it when it would not.
#include <gtest/gtest.h>

#include <vector>

#include <nlohmann/json.hpp>

#include "gateway/mqtt_documents.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::gateway {
namespace {

// A set point as read with `decimals` (the device's decimal point, which its text shows).
ValueChange number(double value, std::string text, int decimals = 1) {
    ValueChange change;
    change.device = "oven";
    change.parameter = "set_point";
    change.value = device::EngineeringValue{};
    change.value->value = value;
    change.text = std::move(text);
    change.decimals = decimals;
    change.unit = "°C";
    change.limits = {0.0, 400.0};
    change.status = "ok";
    return change;
}

// Changes of one parameter that differ in one thing each, against the first.
std::vector<ValueChange> variants() {
    std::vector<ValueChange> all{number(137.0, "137.0"), number(142.5, "142.5"), number(142, "142", 0)};
    all.push_back(number(137.0, "137.0"));
    all.back().unit = "°F";
    all.push_back(number(137.0, "137.0"));
    all.back().limits.max = 300.0;
    all.push_back(number(137.0, "137.0"));
    all.back().limits.min.reset();
    ValueChange stale = number(137.0, "");
    stale.value.reset();
    stale.status = "stale";
    stale.error = "not polled for 3.0 s (polled every 1.0 s)";
    all.push_back(stale);
    ValueChange silent = stale;
    silent.status = "no-reply";
    silent.error = "no reply";
    all.push_back(silent);
    return all;
}

TEST(MqttMeta, EqualInputsMakeAnEqualDocumentAndADifferentDocumentHasDifferentInputs) {
    const auto profile = device::testing::builtin("tc10");
    ASSERT_TRUE(profile);
    const device::Parameter* set_point = profile->find("set_point");
    ASSERT_NE(set_point, nullptr);
    const auto changes = variants();
    for (const device::Parameter* parameter : {set_point, static_cast<const device::Parameter*>(nullptr)}) {
        for (const std::string last_error : {"", "no reply"}) {
            for (std::size_t a = 0; a < changes.size(); ++a) {
                for (std::size_t b = 0; b < changes.size(); ++b) {
                    const bool same_inputs = meta_inputs(changes[a], parameter, last_error) == meta_inputs(changes[b], parameter, last_error);
                    const bool same_document = meta_document(changes[a], parameter, last_error) == meta_document(changes[b], parameter, last_error);
                    EXPECT_EQ(same_inputs, same_document) << "changes " << a << " and " << b << (parameter ? "" : " without a parameter");
                }
            }
        }
    }
    // A new value with the decimals of the last is the usual change: nothing to rebuild.
    EXPECT_EQ(meta_inputs(changes[0], set_point, ""), meta_inputs(number(400.0, "400.0"), set_point, ""));
    EXPECT_NE(meta_inputs(changes[0], set_point, ""), meta_inputs(changes[0], set_point, "no reply"));
}

// A number's range is only ever the value's own limits: none known (no range in the profile, its
// limit words not read), no min/max, never what the word can hold (-3276.8 .. 3276.7 % for the
// AC20's main output); its limit words read, their values.
TEST(HomeAssistantDocuments, ANumbersRangeIsItsLimitsOrNone) {
    const auto ac20 = device::testing::builtin("ac20");
    ASSERT_TRUE(ac20);
    MqttConfig mqtt;
    mqtt.prefix = "loopwire/plant1";
    mqtt.gateway_name = "plant1";
    mqtt.writes = true;
    const device::Parameter& output = *ac20->find("main_output_value");
    const auto before = discovery_document(mqtt, "furnace", *ac20, output);
    EXPECT_EQ(before.topic, "homeassistant/number/plant1_furnace_main_output_value/config");
    EXPECT_FALSE(before.config.contains("min") || before.config.contains("max")) << before.config.dump();

    ValueChange read;
    read.device = "furnace";
    read.parameter = output.name;
    read.value = device::EngineeringValue{};
    read.value->value = 42.0;
    read.text = "42.0";
    read.decimals = 1;
    read.unit = "%";
    read.status = "ok";
    read.limits = {0.0, 100.0};  // main_output_low_limit and main_output_high_limit as read
    const auto after = discovery_document(mqtt, "furnace", *ac20, output, &read);
    EXPECT_EQ(after.config.at("min"), 0.0);
    EXPECT_EQ(after.config.at("max"), 100.0);
    read.limits = {50.0, 50.0};  // limits met: no range Home Assistant would refuse
    const auto met = discovery_document(mqtt, "furnace", *ac20, output, &read);
    EXPECT_FALSE(met.config.contains("min") || met.config.contains("max")) << met.config.dump();

    // The ramp/soak controller's set value has no limit in its profile: no ±3276.8 °C.
    const auto rampsoak = device::testing::builtin("rampsoak");
    ASSERT_TRUE(rampsoak);
    read.parameter = "set_value";
    read.unit = "°C";
    read.limits = {};
    const auto set_value = discovery_document(mqtt, "kiln", *rampsoak, *rampsoak->find("set_value"), &read);
    EXPECT_FALSE(set_value.config.contains("min") || set_value.config.contains("max")) << set_value.config.dump();
}

// The AC20's local/remote bit is a select (local, remote), so that Home Assistant can switch the
// device to remote before it writes a set point; its state template knows only those words.
TEST(HomeAssistantDocuments, TheAc20sLocalRemoteIsASelect) {
    const auto ac20 = device::testing::builtin("ac20");
    ASSERT_TRUE(ac20);
    MqttConfig mqtt;
    mqtt.prefix = "loopwire/plant1";
    mqtt.gateway_name = "plant1";
    mqtt.writes = true;
    const auto document = discovery_document(mqtt, "furnace", *ac20, *ac20->find("local_remote"));
    EXPECT_EQ(document.topic, "homeassistant/select/plant1_furnace_local_remote/config");
    EXPECT_EQ(document.config.at("options"), nlohmann::json::array({"local", "remote"}));
    EXPECT_EQ(document.config.at("command_topic"), "loopwire/plant1/furnace/local_remote/set");
    EXPECT_EQ(document.config.at("value_template"), "{{ value if value in [\"local\",\"remote\"] else None }}");
}

// The gateway is a device of its own, which every controller is reached through; the
// dashboard's address is each device's configuration_url.
TEST(HomeAssistantDocuments, TheGatewayIsTheDeviceEveryControllerIsReachedThrough) {
    const auto tc10 = device::testing::builtin("tc10");
    ASSERT_TRUE(tc10);
    MqttConfig mqtt;
    mqtt.prefix = "loopwire/plant1";
    mqtt.gateway_name = "plant1";
    mqtt.configuration_url = "http://gateway.example:8080/";
    const auto gateway = gateway_document(mqtt);
    EXPECT_EQ(gateway.topic, "homeassistant/binary_sensor/plant1_status/config");
    EXPECT_EQ(gateway.config.at("device").at("identifiers"), nlohmann::json::array({"plant1"}));
    EXPECT_FALSE(gateway.config.at("device").at("sw_version").get<std::string>().empty());
    EXPECT_EQ(gateway.config.at("device").at("configuration_url"), "http://gateway.example:8080/");
    EXPECT_EQ(gateway.config.at("payload_on"), "online");
    const auto sensor = discovery_document(mqtt, "oven", *tc10, *tc10->find("measured_value"));
    EXPECT_EQ(sensor.config.at("device").at("via_device"), "plant1");
    // A controller named "gateway" is still not the gateway.
    EXPECT_EQ(discovery_document(mqtt, "gateway", *tc10, *tc10->find("measured_value")).config.at("device").at("identifiers"),
              nlohmann::json::array({"plant1_gateway"}));
    EXPECT_EQ(sensor.config.at("device").at("configuration_url"), "http://gateway.example:8080/");
}

// The thermostat: heating or idle from the control output where it is polled, its mode read
// from the mode word, the slider's range the set point's limits as the device holds them.
TEST(HomeAssistantDocuments, TheThermostatSaysWhatTheLoopDoesWithinTheDevicesLimits) {
    const auto tc10 = device::testing::builtin("tc10");
    ASSERT_TRUE(tc10);
    MqttConfig mqtt;
    mqtt.prefix = "loopwire/plant1";
    mqtt.gateway_name = "plant1";
    ControlLoopSample sample{"°C", 1, true};
    sample.out_polled = true;
    sample.sp_limits = {-50.0, 450.0};
    const auto climate = climate_document(mqtt, "oven", *tc10, sample);
    ASSERT_TRUE(climate);
    EXPECT_EQ(climate->config.at("action_topic"), "loopwire/plant1/oven/output_power");
    EXPECT_EQ(climate->config.at("mode_state_topic"), "loopwire/plant1/oven/control_state");
    EXPECT_EQ(climate->config.at("min_temp"), -50.0);
    EXPECT_EQ(climate->config.at("max_temp"), 450.0);
    EXPECT_EQ(climate->config.at("temperature_unit"), "C");
    sample.out_polled = false;
    sample.sp_limits = {};
    const auto without = climate_document(mqtt, "oven", *tc10, sample);
    ASSERT_TRUE(without);
    EXPECT_FALSE(without->config.contains("action_topic")) << "an action with no output polled";
    EXPECT_FALSE(without->config.contains("min_temp") || without->config.contains("max_temp"));
}

}  // namespace
}  // namespace loopwire::gateway
