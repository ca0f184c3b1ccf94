// DEVICE@UNIT as users type it (client/device_client.hpp): the unit is plain decimal 1..255,
// then within the addresses the device's manual allows (profile unit_ids).
#include <gtest/gtest.h>

#include "client/device_client.hpp"

namespace loopwire::device {
namespace {

TEST(DeviceAddress, UnitIsPlainDecimalOneTo255) {
    auto address = split_device_address("tc10@255");
    ASSERT_TRUE(address) << address.error().message;
    EXPECT_EQ(address->id, "tc10");
    EXPECT_EQ(address->unit, 255);
    EXPECT_EQ(split_device_address("tc10")->unit, 1);  // no unit: the usual factory address
    for (const char* text : {"tc10@0", "tc10@256", "tc10@+3", "tc10@ 3", "tc10@3x", "tc10@0x3", "tc10@", "tc10@99999999999999999999"}) {
        auto refused = split_device_address(text);
        ASSERT_FALSE(refused) << text;
        EXPECT_EQ(refused.error().kind, ErrorKind::usage) << text;
        EXPECT_NE(refused.error().message.find("1..255"), std::string::npos) << refused.error().message;
    }
}

// AC20 Introduction "Each slave has a unique address ranging from 1 to 255"; ramp/soak §4.2
// "1~255"; TC10 §5.3.11 #131 Add "0 (oFF) ... 254": each manual's limit, not Modbus's 247.
TEST(DeviceAddress, EachDeviceTakesTheUnitsItsManualAllows) {
    for (const char* text : {"ac20@255", "rampsoak@255", "tc10@254", "ac20@248"}) {
        auto address = parse_device_address(text);
        ASSERT_TRUE(address) << text << ": " << address.error().message;
    }
    EXPECT_EQ(parse_device_address("ac20@255")->unit, 255);
    auto refused = parse_device_address("tc10@255");
    ASSERT_FALSE(refused);
    EXPECT_EQ(refused.error().kind, ErrorKind::usage);
    EXPECT_NE(refused.error().message.find("1..254"), std::string::npos) << refused.error().message;
}

TEST(DeviceAddress, AnUnknownIdNamesTheKnownOnes) {
    auto address = parse_device_address("oven@3");
    ASSERT_FALSE(address);
    EXPECT_NE(address.error().message.find("tc10"), std::string::npos) << address.error().message;
}

}  // namespace
}  // namespace loopwire::device
