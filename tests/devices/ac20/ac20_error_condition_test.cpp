// The AC20's start-up error conditions through the wire (ENG. 824E rev. 1, "List of error
// codes" and the paragraphs after it; choices in src/devices/ac20/ac20_error_condition.cpp).
#include <gtest/gtest.h>

#include "ac20_test_support.hpp"
#include "codec/pdu.hpp"
#include "simulation/simulator_harness.hpp"

namespace loopwire::device {
namespace {

using namespace testing;
using namespace ac20_testing;

constexpr std::uint16_t carbon_potential = 123;  // a process value: outside the three areas
constexpr std::uint16_t main_set_point = 138;    // control mode, menu group 1 "St.Pn"
constexpr std::uint16_t set_point_high_limit = 1012;
constexpr std::uint16_t bar_graph_low = 2502, bar_graph_high = 2503;  // configuration menu 6

std::string read_reply(Simulated& dev, std::uint16_t address) {
    return dev.send(codec::read_request(codec::FunctionCode::read_holding_registers, address, 1));
}

// The same saved contents in a device switched on again (--state across a restart).
std::unique_ptr<Simulated> power_cycled(Simulated& before) {
    auto after = std::make_unique<Simulated>("ac20");
    EXPECT_TRUE(after->device().load_saved(before.device().saved_values()).empty());
    return after;
}

// Configuration menu 6 programmed (bar graph low above high) and the power switched off before
// the menu was closed: the device starts in error 101 (menu 1 checks the bar graph against the
// primary variable's span first).
std::unique_ptr<Simulated> with_configuration_error() {
    Simulated before("ac20");
    enter_configuration(before);
    EXPECT_EQ(before.write(bar_graph_low, 150), echo_word(bar_graph_low, 150));
    EXPECT_EQ(before.write(bar_graph_high, 100), echo_word(bar_graph_high, 100));
    return power_cycled(before);
}

TEST(Ac20ErrorCondition, ConfigurationErrorAtStartUpAnswersOnlyTheThreeAreas_ErrorCodes101To106) {
    auto dev = with_configuration_error();
    EXPECT_EQ(read_reply(*dev, carbon_potential), "83 65") << "a process value: error 101";
    EXPECT_EQ(dev->read(bar_graph_low, 2), (Words{150, 100})) << "configuration words: the values";
    EXPECT_EQ(dev->word(main_set_point), 80) << "control mode words: the value";
    EXPECT_EQ(dev->read(4000, 1), (Words{0})) << "security code mode words: the value";
    EXPECT_EQ(dev->send(codec::read_request(codec::FunctionCode::read_coils, 218, 1)), "81 65");
    // Accepted sets: bit 218, word 347; a control mode word is not among them.
    go_remote(*dev);
    EXPECT_EQ(dev->write(main_set_point, 90), "86 65");
    EXPECT_EQ(dev->word(main_set_point), 80);
    // Programming the menu right and leaving through 3051 restarts the device without error.
    ASSERT_EQ(dev->write(347, 0), echo_word(347, 0));
    EXPECT_EQ(dev->write(bar_graph_high, 180), echo_word(bar_graph_high, 180));
    EXPECT_EQ(dev->write(bar_graph_low, 20), echo_word(bar_graph_low, 20));
    EXPECT_EQ(dev->write(3005, 1), echo_word(3005, 1));
    leave_to_control(*dev);
    EXPECT_EQ(dev->read(carbon_potential, 1).size(), 1u);
    EXPECT_EQ(dev->write(main_set_point, 90), echo_word(main_set_point, 90));
}

// The set point high limit (group 5) lowered under the set point: after a restart group 1
// holds a value outside its range, error 151. Control mode words are accepted then, and a
// good set point ends the condition at once.
TEST(Ac20ErrorCondition, ControlModeErrorAtStartUpEndsWhenTheValueIsFixed_ErrorCodes151To160) {
    Simulated before("ac20");
    go_remote(before);
    ASSERT_EQ(before.write(set_point_high_limit, 50), echo_word(set_point_high_limit, 50));
    EXPECT_EQ(before.read(carbon_potential, 1).size(), 1u) << "no check until the next start";
    auto dev = power_cycled(before);
    EXPECT_EQ(read_reply(*dev, carbon_potential), "83 97") << "error 151";
    EXPECT_EQ(dev->word(set_point_high_limit), 50);
    go_remote(*dev);
    EXPECT_EQ(dev->write(main_set_point, 60), "86 03") << "still above the limit";
    // Set points 1-4 all share the limit (factory 0.80 %C each): the last one fixed ends it.
    for (std::uint16_t set_point = main_set_point; set_point < main_set_point + 4; ++set_point) {
        EXPECT_EQ(read_reply(*dev, carbon_potential), "83 97") << "set point " << set_point - main_set_point + 1;
        EXPECT_EQ(dev->write(set_point, 45), echo_word(set_point, 45));
    }
    EXPECT_EQ(dev->read(carbon_potential, 1).size(), 1u);
}

TEST(Ac20ErrorCondition, LoadingControlDefaultsIsAcceptedInAControlModeErrorOnly_ErrorCodes) {
    Simulated before("ac20");
    go_remote(before);
    ASSERT_EQ(before.write(set_point_high_limit, 50), echo_word(set_point_high_limit, 50));
    auto control_error = power_cycled(before);
    go_remote(*control_error);
    EXPECT_EQ(set_bit(*control_error, 223), echo_bit(223)) << "bit 223: every group's defaults";
    EXPECT_EQ(control_error->read(carbon_potential, 1).size(), 1u) << "the defaults are congruent";
    auto configuration_error = with_configuration_error();
    go_remote(*configuration_error);
    EXPECT_EQ(set_bit(*configuration_error, 223), "85 65");
}

// "If a configuration or control mode or calibration error occurs at start up and no action is
// taken, the device will reset after a 30 second time-out. In configuration mode, the time-out
// will be disable." The reset is a power-on: local (Note 5), so a security code mode write that
// was accepted is refused with 10 afterwards. Protocol time: not scaled by --speed.
TEST(Ac20ErrorCondition, ResetsThirtySecondsAfterTheLastActionOutsideConfigurationMode_ErrorCodes) {
    auto dev = with_configuration_error();
    go_remote(*dev);
    ASSERT_EQ(dev->write(348, 0), echo_word(348, 0));  // security code mode
    auto keep_polling = [&](double seconds) {
        for (double t = 0; t < seconds - 1e-9; t += 1.0) {
            dev->wait(1.0);
            EXPECT_EQ(dev->read(4000, 1).size(), 1u);  // security words answer; line activity
        }
    };
    keep_polling(29);
    EXPECT_EQ(dev->write(4000, 0), echo_word(4000, 0)) << "29 s: no reset yet; this write is an action";
    keep_polling(29);
    EXPECT_EQ(dev->write(4000, 0), echo_word(4000, 0)) << "29 s after the last action";
    keep_polling(31);
    EXPECT_EQ(dev->write(4000, 0), "86 0A") << "reset: local again";
    EXPECT_EQ(read_reply(*dev, carbon_potential), "83 65") << "and in error again";

    auto configuring = with_configuration_error();
    go_remote(*configuring);
    ASSERT_EQ(configuring->write(347, 0), echo_word(347, 0));
    for (int second = 0; second < 40; ++second) {
        configuring->wait(1.0);
        (void)configuring->read(bar_graph_low, 1);
    }
    EXPECT_EQ(configuring->write(bar_graph_high, 180), echo_word(bar_graph_high, 180))
        << "configuration mode: no time-out, still remote and configuring";
}

}  // namespace
}  // namespace loopwire::device
