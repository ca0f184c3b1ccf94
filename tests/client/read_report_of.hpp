#pragma once
// A read report as DeviceClient::read gives it for these raw words, for tests of what the app
// does with readings (dump documents, monitor rows) without a device.
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "client/device_client.hpp"
#include "profile/values.hpp"

namespace loopwire::app::testing {

inline device::ReadReport report_of(const device::Profile& profile,
                                    const std::vector<std::pair<std::string, std::uint16_t>>& words) {
    device::ReadReport report;
    for (const auto& [name, raw] : words) report.raw[name] = raw;
    for (const auto& [name, raw] : words) {
        const auto* parameter = profile.find(name);
        auto value = device::decode_value(*parameter, raw, report.raw);
        EXPECT_TRUE(value) << name;
        report.readings.push_back(device::ParameterReading{parameter, *value, {}});
    }
    return report;
}

}  // namespace loopwire::app::testing
