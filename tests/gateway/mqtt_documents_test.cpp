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

}  // namespace
}  // namespace loopwire::gateway
