// The right device or none: the identification words read with a poll decide whether the poll
// is of the device named (client/identity_check.hpp, client/monitor_state.hpp).
#include <gtest/gtest.h>

#include "client/identity_check.hpp"
#include "client/monitor_state.hpp"
#include "client/read_report_of.hpp"
#include "common/result.hpp"

namespace loopwire::device {
namespace {

using app::testing::report_of;

std::shared_ptr<const Profile> profile(const std::string& id) {
    auto loaded = builtin_profile(id);
    EXPECT_TRUE(loaded) << id;
    return *loaded;
}

ReadReport refused(std::uint8_t code, const std::string& message) {
    ReadReport report;
    report.first_error = Error{ErrorKind::exception, message, code};
    return report;
}

TEST(JudgeIdentity, HoldsWrongOrUnknownFromTheWordsRead) {
    const auto tc10 = profile("tc10");
    EXPECT_EQ(judge_identity(*tc10, report_of(*tc10, {{"instrument_id", 20}})).kind, IdentityVerdict::Kind::holds);
    const auto wrong = judge_identity(*tc10, report_of(*tc10, {{"instrument_id", 0x8000}}));
    EXPECT_EQ(wrong.kind, IdentityVerdict::Kind::wrong);
    EXPECT_EQ(wrong.reason, "its instrument_id (word 21) reads -32768 where the tc10 profile expects 20");
    // No such word at that unit: another device. A device busy with an error condition: unjudged.
    EXPECT_EQ(judge_identity(*tc10, refused(2, "illegal data address")).kind, IdentityVerdict::Kind::wrong);
    EXPECT_EQ(judge_identity(*tc10, refused(4, "slave device failure")).kind, IdentityVerdict::Kind::unknown);
}

class IdentifiedPolls : public ::testing::Test {
protected:
    std::shared_ptr<const Profile> tc10 = profile("tc10");
    const Parameter* pv = tc10->find("measured_value");
    WatchedDevice device = watch("tc10@1", {pv}, tc10.get());
    MonitorClock::time_point now = MonitorClock::now();

    void answer(std::uint16_t instrument_id) {
        record_outcome(device, report_of(*tc10, {{"decimal_point", 1}, {"measured_value", 250}, {"instrument_id", instrument_id}}), std::nullopt, now);
    }
};

TEST_F(IdentifiedPolls, TheFirstPollReadsTheWordsAndAWrongDeviceKeepsNoValue) {
    EXPECT_EQ(identity_words_due(device), std::vector<const Parameter*>{tc10->find("instrument_id")});
    EXPECT_EQ(with_identity_words({pv}, device).size(), 2u);
    answer(0x8000);
    EXPECT_EQ(device.status, DeviceStatus::wrong_device);
    EXPECT_FALSE(device.values[0].fresh);
    EXPECT_FALSE(device.values[0].last.has_value());  // the word it gave is not taken for a value
    EXPECT_NE(device.last_error.find("the unit is not tc10@1: its instrument_id"), std::string::npos) << device.last_error;
    EXPECT_EQ(value_status(device, device.values[0]), "error");  // values: DESIGN's words; the device says why
    EXPECT_EQ(identity_words_due(device).size(), 1u);  // asked again with the next poll
}

TEST_F(IdentifiedPolls, ConfirmedOnceThenCheckedAgainAfterEveryOutage) {
    answer(20);
    EXPECT_EQ(device.status, DeviceStatus::ok);
    EXPECT_TRUE(device.values[0].fresh);
    EXPECT_TRUE(identity_words_due(device).empty());  // no extra words while it keeps answering
    record_poll(device, {}, false, "timeout", now);
    EXPECT_EQ(identity_words_due(device).size(), 1u);
    answer(20);
    record_line_down(device, "serial port hung up");
    EXPECT_EQ(identity_words_due(device).size(), 1u);
    answer(0x8000);  // another device was wired in meanwhile
    EXPECT_EQ(device.status, DeviceStatus::wrong_device);
}

TEST_F(IdentifiedPolls, AnUnjudgedPollKeepsItsValuesAndAsksAgain) {
    ReadReport report = report_of(*tc10, {{"decimal_point", 1}, {"measured_value", 250}});
    report.first_error = Error{ErrorKind::exception, "slave device failure", 4};
    record_outcome(device, report, std::nullopt, now);
    EXPECT_EQ(device.status, DeviceStatus::ok);
    EXPECT_EQ(identity_words_due(device).size(), 1u);
}

TEST(UncheckedPolls, ReadNoIdentificationWords) {
    const auto tc10 = profile("tc10");
    auto device = watch("tc10@1", {tc10->find("measured_value")});
    EXPECT_TRUE(identity_words_due(device).empty());
    record_outcome(device, report_of(*tc10, {{"decimal_point", 1}, {"measured_value", 250}}), std::nullopt, MonitorClock::now());
    EXPECT_EQ(device.status, DeviceStatus::ok);
}

TEST(GatewayExceptions, ZeroAhAndZeroBhAreNoReplyNotPartial) {
    const auto tc10 = profile("tc10");
    for (const std::uint8_t code : {std::uint8_t{0x0A}, std::uint8_t{0x0B}}) {
        auto device = watch("tc10@4", {tc10->find("measured_value")});
        record_outcome(device, refused(code, "gateway target device failed to respond"), std::nullopt, MonitorClock::now());
        EXPECT_EQ(device.status, DeviceStatus::no_reply) << int(code);
    }
    auto device = watch("tc10@4", {tc10->find("measured_value")});
    record_outcome(device, refused(2, "illegal data address"), std::nullopt, MonitorClock::now());
    EXPECT_EQ(device.status, DeviceStatus::partial);  // the device itself refused: it answers
}

}  // namespace
}  // namespace loopwire::device
