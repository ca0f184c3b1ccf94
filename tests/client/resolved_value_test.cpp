// The one resolved view of a value (client/resolved_value.hpp) that every front formats from:
// decimals as a number (never parsed back out of a text), the one fallback for limits, and a
// polled value's status and age as of the moment the view is taken.
#include <gtest/gtest.h>

#include <chrono>

#include "client/resolved_value.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

using namespace std::chrono_literals;

const Profile& tc10() {
    static const auto profile = testing::builtin("tc10");
    return *profile;
}

EngineeringValue decoded(const Parameter& parameter, std::uint16_t raw, const RawValues& known) {
    auto value = decode_value(parameter, raw, known);
    if (!value) throw std::runtime_error(value.error().message);
    return *value;
}

TEST(ResolvedValue, DecimalsAreTheValuesOwnAsANumberWhereAnotherWordSetsThem) {
    const Parameter& set_point = testing::parameter(tc10(), "set_point");
    const RawValues known{{"decimal_point", 1}, {"set_point_low_limit", 0}, {"set_point_high_limit", 4000}};
    const EngineeringValue value = decoded(set_point, 1505, known);
    const ResolvedValue resolved = resolve_value(set_point, &value, known);
    EXPECT_EQ(resolved.text, "150.5");
    EXPECT_EQ(resolved.decimals, 1);
    // A whole number keeps its decimals: the count is not read off the text.
    const EngineeringValue whole = decoded(set_point, 1500, known);
    EXPECT_EQ(resolve_value(set_point, &whole, known).decimals, 1);
    EXPECT_EQ(resolve_value(set_point, nullptr, {}).decimals, 0) << "not read yet";
    // The limits as the device holds them: SP.LL and SP.HL at the present decimals.
    EXPECT_EQ(resolved.limits.min, 0.0);
    EXPECT_EQ(resolved.limits.max, 400.0);
}

TEST(ResolvedValue, LimitsHaveOneFallbackAndNeverAnotherNumber) {
    const Parameter& band = testing::parameter(tc10(), "proportional_band");  // 1 … 9999 display counts
    const EngineeringValue value = decoded(band, 150, {{"decimal_point", 1}});
    // Its decimals word read beside it: the counts scaled by it.
    const ResolvedValue read = resolve_value(band, &value, {{"decimal_point", 1}});
    EXPECT_EQ(read.limits.min, 0.1);
    EXPECT_EQ(read.limits.max, 999.9);
    // Not read beside it: the fallback scales the counts by the value's own decimals, the same numbers.
    EXPECT_EQ(resolve_value(band, &value, {}).limits, read.limits);
    // Nothing to scale them by: no number at all, never the unscaled counts.
    EXPECT_EQ(resolve_value(band, nullptr, {}).limits, ValueLimits{});
    // A bound set by a parameter not read: none, and the name of what sets it for a front to say.
    const Parameter& set_point = testing::parameter(tc10(), "set_point");
    EXPECT_FALSE(resolve_value(set_point, nullptr, {{"decimal_point", 1}}).limits.max);
    EXPECT_EQ(bounding_parameter(set_point.max), "set_point_high_limit");
    EXPECT_FALSE(bounding_parameter(band.max)) << "a fixed bound names no parameter";
}

TEST(ResolvedValue, APolledValueCarriesItsStatusAndItsAgeAsOfTheView) {
    const Parameter& set_point = testing::parameter(tc10(), "set_point");
    WatchedDevice device = watch("tc10@3", {&set_point});
    device.known = {{"decimal_point", 1}, {"set_point_low_limit", 0}, {"set_point_high_limit", 4000}};
    const MonitorClock::time_point read_at{};
    WatchedValue& value = device.values.at(0);
    value.last = decoded(set_point, 1505, device.known);
    value.read_at = read_at + 10s;
    value.fresh = true;
    device.status = DeviceStatus::ok;
    const ResolvedValue current = resolve_watched(device, value, read_at + 12500ms);
    EXPECT_EQ(current.status, "ok");
    EXPECT_EQ(current.age, 2.5);
    EXPECT_EQ(current.text, "150.5");
    EXPECT_TRUE(current.error.empty());

    // The next poll got no reply: the last value is kept, its status says why it is not current.
    value.fresh = false;
    value.error = "timeout: no reply within 1 s";
    device.status = DeviceStatus::no_reply;
    const ResolvedValue silent = resolve_watched(device, value, read_at + 20s);
    EXPECT_EQ(silent.status, "no-reply");
    EXPECT_EQ(silent.age, 10.0);
    EXPECT_EQ(silent.text, "150.5");
    EXPECT_EQ(silent.error, "timeout: no reply within 1 s");

    // What answered is not the configured device: none of its values is this device's.
    device.status = DeviceStatus::wrong_device;
    EXPECT_EQ(resolve_watched(device, value, read_at + 20s).status, "error");
}

}  // namespace
}  // namespace loopwire::device
