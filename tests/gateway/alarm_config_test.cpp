// [[alarms.limits]] as `loopwire gateway --check` reads it: every mistake with its file and line.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "gateway/gateway_config.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::gateway {
namespace {

using ::testing::HasSubstr;

Result<GatewayConfig> parse(const std::string& text) {
    return parse_gateway_config(text, "plant.toml", device::testing::builtin_registry());
}

// One TC10 polling PV and SP, then `alarms` from line 9 on.
std::string plant(const std::string& alarms) {
    return "[[lines]]\n"                                          // 1
           "name = \"l1\"\n"                                      // 2
           "link = \"rtu:virtual\"\n"                             // 3
           "[[lines.devices]]\n"                                  // 4
           "name = \"oven\"\n"                                    // 5
           "device = \"tc10@3\"\n"                                // 6
           "parameters = [\"measured_value\", \"set_point\", \"control_state\"]\n"  // 7
           "\n"                                                   // 8
           + alarms;
}

TEST(AlarmConfig, ALimitAlarmIsReadWithItsDefaults) {
    auto config = parse(plant("[[alarms.limits]]\ndevice = \"oven\"\nparameter = \"PV\"\nkind = \"high\"\nlimit = 250\n"
                              "deadband = 2.5\non_delay = \"5s\"\nseverity = \"critical\"\n"));
    ASSERT_TRUE(config) << config.error().message;
    ASSERT_EQ(config->alarm_limits.size(), 1U);
    const alarms::LimitAlarm& alarm = config->alarm_limits[0];
    EXPECT_EQ(alarm.device, "oven");
    EXPECT_EQ(alarm.parameter, "measured_value");  // the alias resolved
    EXPECT_EQ(alarm.name, "measured_value_high");
    EXPECT_EQ(alarm.limit, 250.0);
    EXPECT_EQ(alarm.deadband, 2.5);
    EXPECT_EQ(alarm.on_delay, std::chrono::milliseconds(5000));
    EXPECT_EQ(alarm.off_delay, std::chrono::milliseconds(0));
    EXPECT_EQ(alarm.severity, alarms::Severity::critical);
}

TEST(AlarmConfig, EveryMistakeIsSaidWithItsLine) {
    const auto config = parse(plant("[[alarms.limits]]\n"         // 9
                                    "device = \"kiln\"\n"         // 10
                                    "parameter = \"PV\"\n"        // 11
                                    "kind = \"high\"\n"           // 12
                                    "limit = 1\n"                 // 13
                                    "[[alarms.limits]]\n"         // 14
                                    "device = \"oven\"\n"         // 15
                                    "parameter = \"control_state\"\n"  // 16
                                    "kind = \"high\"\n"           // 17
                                    "limit = 1\n"                 // 18
                                    "[[alarms.limits]]\n"         // 19
                                    "device = \"oven\"\n"         // 20
                                    "parameter = \"output_power\"\n"  // 21
                                    "kind = \"deviation\"\n"      // 22
                                    "limit = 1\n"                 // 23
                                    "severity = \"urgent\"\n"     // 24
                                    "colour = \"red\"\n"));       // 25
    ASSERT_FALSE(config);
    const std::string& message = config.error().message;
    EXPECT_THAT(message, HasSubstr("plant.toml:10: alarms.limits[0].device: no device \"kiln\""));
    EXPECT_THAT(message, HasSubstr("plant.toml:16: alarms.limits[1].parameter: \"control_state\" is not a number"));
    EXPECT_THAT(message, HasSubstr("plant.toml:19: alarms.limits[2]: a deviation alarm needs `setpoint`"));
    EXPECT_THAT(message, HasSubstr("plant.toml:21: alarms.limits[2].parameter: \"output_power\" is not polled"));
    EXPECT_THAT(message, HasSubstr("plant.toml:24: alarms.limits[2].severity: \"urgent\" is not a severity"));
    EXPECT_THAT(message, HasSubstr("plant.toml:25: alarms.limits[2].colour: unknown key"));
}

TEST(AlarmConfig, TwoAlarmsOfOneNameOnADeviceAreRefused) {
    const std::string one = "[[alarms.limits]]\ndevice = \"oven\"\nparameter = \"PV\"\nkind = \"high\"\nlimit = 1\n";
    const auto config = parse(plant(one + one));
    ASSERT_FALSE(config);
    EXPECT_THAT(config.error().message, HasSubstr("has two alarms named \"measured_value_high\""));
}

}  // namespace
}  // namespace loopwire::gateway
