// The public API (include/loopwire/) against simulated devices on loopback TCP.
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <loopwire/loopwire.hpp>

namespace {

using loopwire::Device;
using loopwire::Failure;
using loopwire::Link;
using loopwire::Simulator;

// Runs `call` and returns the Failure it throws; fails the test when it throws none.
template <typename Call>
Failure failure_of(Call&& call) {
    try {
        call();
    } catch (const Failure& failure) {
        return failure;
    }
    ADD_FAILURE() << "expected a loopwire::Failure, none was thrown";
    return Failure(Failure::Kind::usage, "none thrown");
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

class SimulatedTc10 : public ::testing::Test {
protected:
    Simulator simulator = Simulator::start("tcp://127.0.0.1:0", {"tc10@3"});
    Link link = Link::open(simulator.url(), {std::chrono::milliseconds(2000), 0});
    Device oven{link, "tc10@3"};
};

TEST(Version, IsTheProjectVersion) {
    EXPECT_EQ(loopwire::version(), LOOPWIRE_EXPECTED_VERSION);
    EXPECT_EQ(std::string(loopwire::version()), std::to_string(loopwire::version_major) + "." +
                                                    std::to_string(loopwire::version_minor) + "." +
                                                    std::to_string(loopwire::version_patch));
}

TEST_F(SimulatedTc10, SimulatorServesOnThePortTheSystemPicked) {
    EXPECT_NE(simulator.port(), 0);
    EXPECT_EQ(simulator.url(), "tcp://127.0.0.1:" + std::to_string(simulator.port()));
}

TEST_F(SimulatedTc10, ReadsByNameOrMnemonicInEngineeringUnits) {
    const loopwire::Reading by_name = oven.read("set_point");
    EXPECT_EQ(by_name.name, "set_point");
    EXPECT_EQ(by_name.mnemonic, "SP");
    EXPECT_EQ(by_name.status, "ok");
    EXPECT_FALSE(by_name.failed());
    ASSERT_TRUE(by_name.number.has_value());
    EXPECT_FALSE(by_name.text.empty());

    const loopwire::Reading by_mnemonic = oven.read("fil");  // mnemonics in any case
    EXPECT_EQ(by_mnemonic.name, "input_filter");
    EXPECT_EQ(by_mnemonic.unit, "s");

    const loopwire::Reading label = oven.read("temperature_unit");
    EXPECT_FALSE(label.number.has_value()) << "an enum reads as its label";
    EXPECT_TRUE(label.text == "C" || label.text == "F") << label.text;
    EXPECT_EQ(oven.profile_id(), "tc10");
    EXPECT_EQ(oven.unit(), 3);
}

// The reading is the resolved view every front shows: the unit from the device's
// unit word, not the profile's default (which a TC10's temperatures do not have), and the
// limits as numbers from the words that bound the value.
TEST_F(SimulatedTc10, ReadingCarriesTheDevicesUnitLimitsAndStatus) {
    const loopwire::Reading pv = oven.read("measured_value");
    const std::string degrees = "°" + oven.read("temperature_unit").text;
    EXPECT_EQ(pv.unit, degrees);
    EXPECT_EQ(pv.state, loopwire::ValueStatus::ok);

    oven.write("set_point_low_limit", "-50");
    oven.write("set_point_high_limit", "650");
    const loopwire::Reading sp = oven.read("set_point");
    EXPECT_EQ(sp.unit, degrees);
    ASSERT_TRUE(sp.min && sp.max);
    EXPECT_DOUBLE_EQ(*sp.min, -50.0);
    EXPECT_DOUBLE_EQ(*sp.max, 650.0);

    oven.write("temperature_unit", oven.read("temperature_unit").text == "C" ? "F" : "C");
    EXPECT_NE(oven.read("set_point").unit, degrees) << "the unit follows the unit word as it is now";
}

TEST(Reading, WithoutAReplyIsAnErrorWithItsReason) {
    Simulator simulator = Simulator::start("tcp://127.0.0.1:0", {"tc10@3"});
    Link link = Link::open(simulator.url(), {std::chrono::milliseconds(300), 0});
    Device absent(link, "tc10@4");  // nothing answers at unit 4
    const auto readings = absent.read(std::vector<std::string>{"set_point"});
    ASSERT_EQ(readings.size(), 1u);
    EXPECT_EQ(readings[0].state, loopwire::ValueStatus::error);
    EXPECT_TRUE(readings[0].failed());
    EXPECT_FALSE(readings[0].error.empty());
}

TEST_F(SimulatedTc10, ReadsSeveralNamesAndGroupsInTheOrderAsked) {
    const auto readings = oven.read(std::vector<std::string>{"set_point", "measured_value"});
    ASSERT_EQ(readings.size(), 2u);
    EXPECT_EQ(readings[0].name, "set_point");
    EXPECT_EQ(readings[1].name, "measured_value");

    const auto group = oven.read(std::vector<std::string>{"inP"});
    EXPECT_GT(group.size(), 1u);
    const Failure single = failure_of([&] { oven.read("inP"); });
    EXPECT_EQ(single.kind(), Failure::Kind::usage);
    EXPECT_TRUE(contains(single.what(), "names a group")) << single.what();
}

TEST_F(SimulatedTc10, WrittenSetPointReadsBack) {
    const std::string decimals = oven.read("decimal_point").text;
    const std::string value = decimals == "0" ? "123" : "123.4";
    oven.write("set_point", value);
    const loopwire::Reading back = oven.read("set_point");
    EXPECT_EQ(back.text, value);
    ASSERT_TRUE(back.number.has_value());
    EXPECT_DOUBLE_EQ(*back.number, std::stod(value));

    oven.write({{"set_point", "100"}, {"input_filter", "2.5"}});
    EXPECT_DOUBLE_EQ(*oven.read("set_point").number, 100.0);
    EXPECT_EQ(oven.read("input_filter").text, "2.5");
}

TEST_F(SimulatedTc10, InvalidWritesAreRefusedAndChangeNothing) {
    const std::string before = oven.read("set_point").text;

    const Failure out_of_range = failure_of([&] { oven.write("set_point", "99999"); });
    EXPECT_EQ(out_of_range.kind(), Failure::Kind::usage);
    EXPECT_TRUE(contains(out_of_range.what(), "set_point")) << out_of_range.what();

    const Failure not_a_number = failure_of([&] { oven.write("set_point", "warm"); });
    EXPECT_EQ(not_a_number.kind(), Failure::Kind::usage);

    // One bad value in a list: nothing of the list is written.
    const Failure in_a_list = failure_of([&] { oven.write({{"set_point", "101"}, {"input_filter", "nonsense"}}); });
    EXPECT_EQ(in_a_list.kind(), Failure::Kind::usage);

    const Failure read_only = failure_of([&] { oven.write("measured_value", "1"); });
    EXPECT_EQ(read_only.kind(), Failure::Kind::usage);
    EXPECT_TRUE(contains(read_only.what(), "read-only")) << read_only.what();

    EXPECT_EQ(oven.read("set_point").text, before);
}

TEST_F(SimulatedTc10, UnknownNamesAreUsageFailures) {
    const Failure unknown = failure_of([&] { oven.read("no_such_parameter"); });
    EXPECT_EQ(unknown.kind(), Failure::Kind::usage);
    EXPECT_TRUE(contains(unknown.what(), "no_such_parameter")) << unknown.what();
    EXPECT_EQ(failure_of([&] { oven.write("no_such_parameter", "1"); }).kind(), Failure::Kind::usage);
}

TEST_F(SimulatedTc10, AUnitNotServedIsADeviceException) {
    Device absent(link, "tc10@4");
    const Failure failure = failure_of([&] { absent.read("set_point"); });
    EXPECT_EQ(failure.kind(), Failure::Kind::device_exception) << failure.what();
    EXPECT_EQ(failure.exception_code(), 0x0B) << "gateway target device failed to respond";
}

TEST_F(SimulatedTc10, DevicesAreNamedByBuiltInIdOrProfileFile) {
    Device from_file(link, LOOPWIRE_PROFILE_DIR "/tc10.json@3");
    EXPECT_EQ(from_file.profile_id(), "tc10");
    oven.write("set_point", "111");
    EXPECT_DOUBLE_EQ(*from_file.read("set_point").number, 111.0);

    EXPECT_EQ(failure_of([&] { Device(link, "no_such_device@3"); }).kind(), Failure::Kind::usage);
    EXPECT_EQ(failure_of([&] { Device(link, "tc10@0"); }).kind(), Failure::Kind::usage);
    EXPECT_EQ(failure_of([&] { Device(link, "tc10@255"); }).kind(), Failure::Kind::usage);
    EXPECT_EQ(failure_of([&] { Device(link, LOOPWIRE_PROFILE_DIR "/tc10.json@x"); }).kind(), Failure::Kind::usage);
    EXPECT_EQ(failure_of([&] { Device(link, "no/such/profile.json@3"); }).kind(), Failure::Kind::usage);
}

TEST_F(SimulatedTc10, StoppedSimulatorAnswersNoMore) {
    oven.read("set_point");
    EXPECT_GT(simulator.requests_served(), 0u);
    simulator.stop();
    simulator.stop();  // a second stop does nothing
    const Failure failure = failure_of([&] {
        Link again = Link::open(simulator.url(), {std::chrono::milliseconds(300), 0});
        Device(again, "tc10@3").read("set_point");
    });
    EXPECT_TRUE(failure.kind() == Failure::Kind::link || failure.kind() == Failure::Kind::timeout) << failure.what();
}

TEST(LinkOpening, MalformedUrlsAreUsageFailures) {
    for (const char* url : {"tcp://127.0.0.1:99999", "tcp://127.0.0.1:port", "nonsense:/dev/ttyS0", "rtu:/dev/ttyS0?baud=12345"}) {
        const Failure failure = failure_of([&] { Link::open(url); });
        EXPECT_EQ(failure.kind(), Failure::Kind::usage) << url << ": " << failure.what();
    }
    EXPECT_EQ(failure_of([] { Link::open("rtu:virtual"); }).kind(), Failure::Kind::usage);
}

TEST(SimulatorStart, RefusesWhatItCannotServe) {
    EXPECT_EQ(failure_of([] { Simulator::start("tcp://127.0.0.1:0", {}); }).kind(), Failure::Kind::usage);
    EXPECT_EQ(failure_of([] { Simulator::start("tcp://127.0.0.1:0", {"tc10@3", "ac20@3"}); }).kind(), Failure::Kind::usage);
    EXPECT_EQ(failure_of([] { Simulator::start("tcp://127.0.0.1:0", {"no_such_device@1"}); }).kind(), Failure::Kind::usage);
    EXPECT_EQ(failure_of([] { Simulator::start("tcp://127.0.0.1:99999", {"tc10@3"}); }).kind(), Failure::Kind::usage);

    Simulator first = Simulator::start("tcp://127.0.0.1:0", {"tc10@3"});
    const Failure taken = failure_of([&] { Simulator::start(first.url(), {"tc10@3"}); });
    EXPECT_EQ(taken.kind(), Failure::Kind::link) << taken.what();
}

TEST(SimulatorStart, ServesSeveralDevicesAndProfileFiles) {
    Simulator simulator = Simulator::start("tcp://127.0.0.1:0", {"ac20@1", LOOPWIRE_PROFILE_DIR "/tc10.json@3"},
                                           {30.0, 7});
    Link link = Link::open(simulator.url());
    EXPECT_FALSE(link.describe().empty());
    EXPECT_EQ(Device(link, "tc10@3").read("set_point").status, "ok");
    EXPECT_EQ(Device(link, "ac20@1").profile_id(), "ac20");
    EXPECT_FALSE(Device(link, "ac20@1").read(std::vector<std::string>{"all"}).empty());
}

}  // namespace
