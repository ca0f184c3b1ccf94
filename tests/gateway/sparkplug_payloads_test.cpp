// The Sparkplug B metrics and payloads (gateway/sparkplug/sparkplug_payloads.hpp), decoded here
// with protobuf's own parser: datatypes chosen from the profiles, two's complement of signed
// words, null values with a quality for what is stale or missing, birth properties, commands.
// tests/gateway/sparkplug_check.py decodes the same messages with Python's protobuf.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "gateway/sparkplug/sparkplug_payloads.hpp"
#include "sparkplug/sparkplug_b.pb.h"
#include "support/profile_test_support.hpp"

namespace loopwire::gateway::sparkplug {
namespace {

using ::testing::HasSubstr;
using Payload = loopwire::sparkplug::b::Payload;

std::shared_ptr<const device::Profile> profile(const std::string& id) { return device::testing::builtin(id); }

ValueChange change_of(const device::Parameter& parameter, device::EngineeringValue value, std::string text,
                      std::string status = "ok") {
    ValueChange change;
    change.device = "oven";
    change.parameter = parameter.name;
    change.unit = value.unit;
    change.value = std::move(value);
    change.text = std::move(text);
    change.status = std::move(status);
    change.sampled = std::chrono::system_clock::time_point(std::chrono::milliseconds(1'700'000'000'123));
    return change;
}

Payload decoded(const PayloadWriter& writer) {
    Payload payload;
    EXPECT_TRUE(payload.ParseFromString(writer.bytes()));
    return payload;
}

// The property `key` of a metric, or null.
const Payload::PropertyValue* property(const Payload::Metric& metric, const std::string& key) {
    for (int i = 0; i < metric.properties().keys_size(); ++i) {
        if (metric.properties().keys(i) == key) return &metric.properties().values(i);
    }
    return nullptr;
}

TEST(SparkplugPayloads, DatatypesFollowTheProfile) {
    const auto ac20 = profile("ac20");
    const auto tc10 = profile("tc10");
    ASSERT_TRUE(ac20 && tc10);
    using device::testing::parameter;
    // Whole numbers keep their word's sign; scaled ones are Double (0.85 %C is not exact in a Float).
    EXPECT_EQ(datatype_of(parameter(*ac20, "probe_temperature")), DataType::int16);
    EXPECT_EQ(datatype_of(parameter(*ac20, "carbon_potential")), DataType::float64);
    EXPECT_EQ(datatype_of(parameter(*ac20, "device_status")), DataType::string);  // an enumeration's label
    // The TC10's decimals follow its dP word: Double whatever dP says.
    EXPECT_EQ(datatype_of(parameter(*tc10, "set_point")), DataType::float64);
    // A bit field: its word as UInt16 and one Boolean per named bit, numbered on.
    const auto& alarms = parameter(*tc10, "alarm_status");
    std::uint64_t alias = 40;
    const auto metrics = parameter_metrics(alarms, alias);
    ASSERT_EQ(metrics.size(), 1 + alarms.bit_names.size());
    EXPECT_EQ(metrics[0].type, DataType::uint16);
    EXPECT_EQ(metrics[0].name, alarms.group + "/alarm_status");
    EXPECT_EQ(metrics[0].alias, 40u);
    EXPECT_EQ(metrics[1].type, DataType::boolean);
    EXPECT_EQ(metrics[1].name, alarms.group + "/alarm_status/" + alarms.bit_names.begin()->second);
    EXPECT_EQ(alias, 40u + metrics.size());
}

TEST(SparkplugPayloads, ASignedWordIsTwosComplementInIntValue) {
    const auto ac20 = profile("ac20");
    ASSERT_TRUE(ac20);
    const auto& probe = device::testing::parameter(*ac20, "probe_temperature");
    std::uint64_t alias = 7;
    const auto metric = parameter_metrics(probe, alias).front();
    device::EngineeringValue value;
    value.value = -5.0;
    value.unit = "°C";
    const auto sample = sample_of(metric, change_of(probe, value, "-5"));
    EXPECT_EQ(sample.value, MetricValue{std::int64_t{-5}});
    EXPECT_EQ(sample.quality, quality_good);
    EXPECT_EQ(sample.timestamp, 1'700'000'000'123u);

    PayloadWriter writer(1, 3);
    writer.data_metric(metric, sample, false);
    const Payload payload = decoded(writer);
    EXPECT_EQ(payload.seq(), 3u);
    ASSERT_EQ(payload.metrics_size(), 1);
    const auto& out = payload.metrics(0);
    EXPECT_EQ(out.alias(), 7u);
    EXPECT_FALSE(out.has_name());  // data names a metric by its alias alone
    EXPECT_EQ(out.int_value(), 0xFFFFFFFBu);
    EXPECT_EQ(static_cast<std::int32_t>(out.int_value()), -5);
    EXPECT_FALSE(out.has_properties());
}

TEST(SparkplugPayloads, StaleAndMissingValuesAreNullWithTheirQuality) {
    const auto ac20 = profile("ac20");
    ASSERT_TRUE(ac20);
    const auto& cp = device::testing::parameter(*ac20, "carbon_potential");
    std::uint64_t alias = 1;
    const auto metric = parameter_metrics(cp, alias).front();
    device::EngineeringValue value;
    value.value = 0.85;
    // A stale change carries no value (value_cache.hpp); even if one came, it is not sent.
    auto stale = change_of(cp, value, "0.85", "stale");
    const auto stale_sample = sample_of(metric, stale);
    EXPECT_TRUE(std::holds_alternative<std::monostate>(stale_sample.value));
    EXPECT_EQ(stale_sample.quality, quality_stale);
    auto missing = change_of(cp, value, "", "no-reply");
    missing.value.reset();
    EXPECT_EQ(sample_of(metric, missing).quality, quality_bad);
    // A special state (under-range): no number.
    device::EngineeringValue special;
    special.status = "under-range";
    const auto special_sample = sample_of(metric, change_of(cp, special, "—", "under-range"));
    EXPECT_TRUE(std::holds_alternative<std::monostate>(special_sample.value));
    EXPECT_EQ(special_sample.quality, quality_bad);

    PayloadWriter writer(1, 0);
    writer.data_metric(metric, stale_sample, true);
    const auto out = decoded(writer).metrics(0);
    EXPECT_TRUE(out.is_null());
    EXPECT_EQ(out.value_case(), Payload::Metric::VALUE_NOT_SET);
    const auto* quality = property(out, "Quality");
    ASSERT_NE(quality, nullptr);
    EXPECT_EQ(quality->type(), static_cast<std::uint32_t>(DataType::int32));
    EXPECT_EQ(quality->int_value(), 500u);
}

TEST(SparkplugPayloads, ABirthCarriesNameDatatypeAndProperties) {
    const auto ac20 = profile("ac20");
    ASSERT_TRUE(ac20);
    const auto& sp = device::testing::parameter(*ac20, "main_set_point");
    std::uint64_t alias = 12;
    const auto metric = parameter_metrics(sp, alias).front();
    device::EngineeringValue value;
    value.value = 0.85;
    value.unit = "%C";
    const auto change = change_of(sp, value, "0.85");
    const auto properties = properties_of(metric, &change, true);
    EXPECT_EQ(properties.unit, "%C");
    EXPECT_TRUE(properties.writable);
    EXPECT_EQ(properties.mnemonic, sp.mnemonic);
    // With the node's writes off a host application is told it cannot write, not a DCMD refused.
    const auto writes_off = properties_of(metric, &change, false);
    EXPECT_FALSE(writes_off.writable);
    EXPECT_NE(writes_off, properties) << "turning writes on or off is a new birth";

    PayloadWriter writer(5, 1);
    writer.birth_metric(metric, sample_of(metric, change), &properties);
    const auto out = decoded(writer).metrics(0);
    EXPECT_EQ(out.name(), metric.name);
    EXPECT_EQ(out.alias(), 12u);
    EXPECT_EQ(out.datatype(), static_cast<std::uint32_t>(DataType::float64));
    EXPECT_DOUBLE_EQ(out.double_value(), 0.85);
    ASSERT_NE(property(out, "engUnit"), nullptr);
    EXPECT_EQ(property(out, "engUnit")->string_value(), "%C");
    ASSERT_NE(property(out, "readOnly"), nullptr);
    EXPECT_FALSE(property(out, "readOnly")->boolean_value());
    ASSERT_NE(property(out, "Quality"), nullptr);
    EXPECT_EQ(property(out, "Quality")->int_value(), 192u);
}

// engLow/engHigh are the limits the device holds (its SP.LL/SP.HL, resolved by the polls), as
// the API, MQTT and Home Assistant give them, not the profile's default.
TEST(SparkplugPayloads, ABirthCarriesTheDevicesOwnLimits) {
    const auto tc10 = profile("tc10");
    ASSERT_TRUE(tc10);
    const auto& sp = device::testing::parameter(*tc10, "set_point");
    std::uint64_t alias = 3;
    const auto metric = parameter_metrics(sp, alias).front();
    device::EngineeringValue value;
    value.value = 200.0;
    value.unit = "°C";
    auto change = change_of(sp, value, "200");
    change.limits = {-50.0, 650.0};
    const auto properties = properties_of(metric, &change, true);
    ASSERT_TRUE(properties.low && properties.high);
    EXPECT_DOUBLE_EQ(*properties.low, -50.0);
    EXPECT_DOUBLE_EQ(*properties.high, 650.0);

    PayloadWriter writer(5, 1);
    writer.birth_metric(metric, sample_of(metric, change), &properties);
    const auto out = decoded(writer).metrics(0);
    ASSERT_NE(property(out, "engHigh"), nullptr);
    EXPECT_DOUBLE_EQ(property(out, "engHigh")->double_value(), 650.0);
    ASSERT_NE(property(out, "engLow"), nullptr);
    EXPECT_DOUBLE_EQ(property(out, "engLow")->double_value(), -50.0);

    change.limits = {-50.0, 500.0};
    EXPECT_NE(properties_of(metric, &change, true), properties) << "a new limit is a new birth";
}

TEST(SparkplugPayloads, CommandsAreDecodedAndTurnedIntoWriteTexts) {
    const auto ac20 = profile("ac20");
    ASSERT_TRUE(ac20);
    const auto& sp = device::testing::parameter(*ac20, "main_set_point");
    std::uint64_t alias = 3;
    const auto metric = parameter_metrics(sp, alias).front();

    Payload command;
    auto* by_name = command.add_metrics();
    by_name->set_name(metric.name);
    by_name->set_datatype(static_cast<std::uint32_t>(DataType::float64));
    by_name->set_double_value(0.9);
    auto* by_alias = command.add_metrics();
    by_alias->set_alias(3);
    by_alias->set_datatype(static_cast<std::uint32_t>(DataType::int16));
    by_alias->set_int_value(static_cast<std::uint32_t>(-2));
    auto metrics = decode_command(command.SerializeAsString());
    ASSERT_TRUE(metrics) << metrics.error().message;
    ASSERT_EQ(metrics->size(), 2u);
    EXPECT_EQ((*metrics)[0].name, metric.name);
    EXPECT_EQ((*metrics)[0].value, MetricValue{0.9});
    EXPECT_EQ((*metrics)[1].alias, std::optional<std::uint64_t>{3});
    EXPECT_EQ((*metrics)[1].value, MetricValue{std::int64_t{-2}});  // Int16: signed back

    EXPECT_EQ(write_text(metric, 0.9).value(), "0.9");
    EXPECT_EQ(write_text(metric, std::int64_t{-2}).value(), "-2");
    EXPECT_EQ(write_text(metric, std::string("0.75")).value(), "0.75");
    EXPECT_THAT(write_text(metric, MetricValue{}).error().message, HasSubstr("no value given"));
    EXPECT_THAT(write_text(metric, true).error().message, HasSubstr("a Boolean"));
    EXPECT_THAT(write_text(metric, std::numeric_limits<double>::infinity()).error().message, HasSubstr("not a finite number"));
    const MetricDefinition node_metric{"Node Control/Rebirth", 1, DataType::boolean, nullptr, {}};
    EXPECT_THAT(write_text(node_metric, true).error().message, HasSubstr("not a device parameter"));

    // A birth with writes off says so in both properties a host application reads.
    PayloadWriter writer(5, 1);
    const auto read_only = properties_of(metric, nullptr, false);
    writer.birth_metric(metric, MetricSample{0.85, quality_good, 5}, &read_only);
    const auto born = decoded(writer).metrics(0);
    ASSERT_TRUE(property(born, "writable") && property(born, "readOnly"));
    EXPECT_FALSE(property(born, "writable")->boolean_value());
    EXPECT_TRUE(property(born, "readOnly")->boolean_value());

    // Not protobuf at all: refused in words, never misread.
    auto garbage = decode_command(std::string("\xff\xff\xff\xff\xff", 5));
    ASSERT_FALSE(garbage);
    EXPECT_THAT(garbage.error().message, HasSubstr("not a Sparkplug B payload"));
}

// A Float is the decimal its sender meant: 12.3 in 32 bits widens to 12.300000190734863, which a
// parameter of one or two decimals would refuse; the value within half a Float's step of it that
// has the fewest digits is 12.3. A value truly finer keeps its digits (the write then refuses it
// for them); a Double is taken as it is, at its own precision.
TEST(SparkplugPayloads, AFloatCommandIsTheDecimalItsSenderMeant) {
    const auto tc10 = profile("tc10");
    ASSERT_TRUE(tc10);
    const auto& power = device::testing::parameter(*tc10, "output_power");  // two decimals
    std::uint64_t alias = 7;
    const auto metric = parameter_metrics(power, alias).front();

    Payload command;
    for (const float value : {12.3f, 12.34f, 12.345f, -99.99f, 0.1f, 250.0f}) {
        auto* out = command.add_metrics();
        out->set_alias(7);
        out->set_datatype(static_cast<std::uint32_t>(DataType::float32));
        out->set_float_value(value);
    }
    auto* as_double = command.add_metrics();
    as_double->set_alias(7);
    as_double->set_datatype(static_cast<std::uint32_t>(DataType::float64));
    as_double->set_double_value(12.3);
    auto* finer_double = command.add_metrics();
    finer_double->set_alias(7);
    finer_double->set_datatype(static_cast<std::uint32_t>(DataType::float64));
    finer_double->set_double_value(static_cast<double>(12.3f));  // a Double that truly is 12.300000190734863
    const auto metrics = decode_command(command.SerializeAsString());
    ASSERT_TRUE(metrics) << metrics.error().message;
    ASSERT_EQ(metrics->size(), 8u);
    std::vector<std::string> texts;
    for (const auto& decoded_metric : *metrics) {
        const auto text = write_text(metric, decoded_metric.value);
        ASSERT_TRUE(text) << text.error().message;
        texts.push_back(*text);
    }
    EXPECT_EQ(texts, (std::vector<std::string>{"12.3", "12.34", "12.345", "-99.99", "0.1", "250", "12.3",
                                               "12.300000190734863"}));
    EXPECT_EQ((*metrics)[0].value, MetricValue{12.3});
}

}  // namespace
}  // namespace loopwire::gateway::sparkplug
