// DEVICE@UNIT as users type it (client/device_client.hpp): the unit is plain decimal 1..247.
#include <gtest/gtest.h>

#include "client/device_client.hpp"

namespace loopwire::device {
namespace {

TEST(DeviceAddress, UnitIsPlainDecimalOneTo247) {
    auto address = split_device_address("tc10@247");
    ASSERT_TRUE(address) << address.error().message;
    EXPECT_EQ(address->id, "tc10");
    EXPECT_EQ(address->unit, 247);
    EXPECT_EQ(split_device_address("tc10")->unit, 1);  // no unit: the usual factory address
    for (const char* text : {"tc10@0", "tc10@248", "tc10@+3", "tc10@ 3", "tc10@3x", "tc10@0x3", "tc10@", "tc10@99999999999999999999"}) {
        auto refused = split_device_address(text);
        ASSERT_FALSE(refused) << text;
        EXPECT_EQ(refused.error().kind, ErrorKind::usage) << text;
        EXPECT_NE(refused.error().message.find("1..247"), std::string::npos) << refused.error().message;
    }
}

TEST(DeviceAddress, AnUnknownIdNamesTheKnownOnes) {
    auto address = parse_device_address("oven@3");
    ASSERT_FALSE(address);
    EXPECT_NE(address.error().message.find("tc10"), std::string::npos) << address.error().message;
}

}  // namespace
}  // namespace loopwire::device
