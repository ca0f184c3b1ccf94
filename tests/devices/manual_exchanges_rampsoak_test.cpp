// The ramp/soak manual's example exchanges (rampsoak-pid-rtu-ascii-linking.en.txt §4.7, §5.7,
// §6.7) replayed against its behaviour model through RTU, ASCII and Linking framing; see
// manual_exchanges_test.cpp for the method.
#include <gtest/gtest.h>

#include "codec/ascii.hpp"
#include "codec/rtu.hpp"
#include "devices/manual_exchange_support.hpp"

namespace loopwire::device::testing {
namespace {

constexpr std::uint16_t sv = 0x0000;
constexpr std::uint16_t pv = 0x008A;

SimulationEnvironment served_over(const std::string& framing) {
    SimulationEnvironment environment;
    environment.framing = framing;
    environment.speed = 100.0;
    return environment;
}

// The examples read PV = 100.0 (03E8h): the chamber is held at SV = 100.0 until the PV shown
// (rounded to the display's 0.1) has settled there.
Simulated settled_at_100(const std::string& framing) {
    Simulated device("rampsoak", Model::behaviour, served_over(framing));
    EXPECT_EQ(device.write(sv, 1000), echo_of(codec::write_single_register(sv, 1000)));
    device.wait(60.0);  // 100 min of process time
    return device;
}

const char* const framings[] = {"rtu", "ascii"};

std::string frame_id(const std::string& framing, const std::string& rest) { return "pid-" + framing + "-" + rest; }

// §4.7.1 (RTU) and §5.7 (ASCII) "Reading (Read PV from slave controller 1)".
TEST(ManualExchanges, RampSoak_4_7_1_And_5_7_ReadPv_Example) {
    for (const std::string framing : framings) {
        Simulated device = settled_at_100(framing);
        EXPECT_EQ(replay(device, frame_id(framing, "fc03-req")), printed(frame_id(framing, "fc03-rep"))) << framing;
    }
}

// §4.7.1 / §5.7 exception reply 83h 03h "(Assumed as illegal data value)". §4.6 code 03: "Data
// value is out of setting range"; for a read the value out of range is the quantity: 0
// registers is no read at all.
TEST(ManualExchanges, RampSoak_4_7_1_And_5_7_ReadException3_FromQuantityZero) {
    for (const std::string framing : framings) {
        Simulated device("rampsoak", Model::behaviour, served_over(framing));
        EXPECT_EQ(answer(device, framing, 0x01, Bytes{0x03, 0x00, 0x8A, 0x00, 0x00}),
                  printed(frame_id(framing, "fc03-exc"))) << framing;
    }
}

// §4.7.2 (RTU) and §5.7.1 (ASCII) "Setting (Set SV = 10.0 to slave controller 1)".
TEST(ManualExchanges, RampSoak_4_7_2_And_5_7_1_SetSv_Example) {
    for (const std::string framing : framings) {
        Simulated device("rampsoak", Model::behaviour, served_over(framing));
        EXPECT_EQ(replay(device, frame_id(framing, "fc06-req")), printed(frame_id(framing, "fc06-rep"))) << framing;
        EXPECT_EQ(device.word(sv), 100) << framing;
    }
}

// §4.7.2 / §5.7.1 exception reply 86h 03h "(Assumed as illegal data value)": OUTL (0001h) has
// the setting range 0.0 ~ 100.0 % (§7), so 100.1 % is refused with code 03.
TEST(ManualExchanges, RampSoak_4_7_2_And_5_7_1_SetException3_FromOutlAboveItsRange) {
    for (const std::string framing : framings) {
        Simulated device("rampsoak", Model::behaviour, served_over(framing));
        EXPECT_EQ(answer(device, framing, 0x01, Bytes{0x06, 0x00, 0x01, 0x03, 0xE9}),
                  printed(frame_id(framing, "fc06-exc"))) << framing;
    }
}

// §4.7.3 (RTU) and §5.7.2 (ASCII) "Setting (Set SV = 10.0 and OUTL=100.0 ...)".
TEST(ManualExchanges, RampSoak_4_7_3_And_5_7_2_SetSvAndOutl_Example) {
    for (const std::string framing : framings) {
        Simulated device("rampsoak", Model::behaviour, served_over(framing));
        EXPECT_EQ(replay(device, frame_id(framing, "fc16-req")), printed(frame_id(framing, "fc16-rep"))) << framing;
        EXPECT_EQ(device.read(sv, 2), (Words{100, 1000})) << framing;
    }
}

// §4.7.3 / §5.7.2 exception reply 90h 02h "(Assumed as illegal register address)" (§4.6 code 02:
// "Register address is out of range"): two registers from 00FFh, past the §7 register map.
// AUDIT.md §1, pid-rtu-fc16-exc: the RTU frame is printed with CRC C0 01 (the CRC of 01 80 02);
// the device sends the right CRC, CD C1. The ASCII frame's LRC 6D is right as printed.
TEST(ManualExchanges, RampSoak_4_7_3_And_5_7_2_SetException2_FromAnAddressOutsideTheMap) {
    const Bytes past_the_map{0x10, 0x00, 0xFF, 0x00, 0x02, 0x04, 0x00, 0x64, 0x03, 0xE8};
    Simulated rtu("rampsoak", Model::behaviour, served_over("rtu"));
    EXPECT_EQ(printed("pid-rtu-fc16-exc"), "01 90 02 C0 01");
    EXPECT_EQ(answer(rtu, "rtu", 0x01, past_the_map), "01 90 02 CD C1");
    Simulated ascii("rampsoak", Model::behaviour, served_over("ascii"));
    EXPECT_EQ(answer(ascii, "ascii", 0x01, past_the_map), printed("pid-ascii-fc16-exc"));
}

// §6.7.1 "Read (Read PV from slave controller 1)", also §6.6's checksum example (the same bytes).
TEST(ManualExchanges, RampSoak_6_7_1_LinkingReadPv_Example) {
    Simulated device = settled_at_100("linking");
    EXPECT_EQ(printed("pid-link-ex-checksum"), printed("pid-link-r-req"));
    EXPECT_EQ(replay(device, "pid-link-r-req"), printed("pid-link-r-rep"));
}

// §6.7.2 "Modify (Modify SV = 10.0 ...)" and §6.7.3 "Write (Write SV = 100.0 ...)". The manual
// prints no reply to M or W; §6.1 gives every reply one shape (07h 4Dh ID address data sum),
// so the device echoes address and data in it, and SV holds the value.
TEST(ManualExchanges, RampSoak_6_7_2_And_6_7_3_LinkingModifyAndWriteSv_Example) {
    Simulated device("rampsoak", Model::behaviour, served_over("linking"));
    EXPECT_EQ(replay(device, "pid-link-m-req"), "07 4D 01 00 00 00 64 B2");
    EXPECT_EQ(device.word(sv), 100);
    EXPECT_EQ(replay(device, "pid-link-w-req"), "07 4D 01 00 00 03 E8 39");
    EXPECT_EQ(device.word(sv), 1000);
}

}  // namespace
}  // namespace loopwire::device::testing
