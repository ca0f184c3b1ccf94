// Every place the AC20 manual (ENG. 824E rev. 1) says a bit or word cannot be modified in a
// mode, through the wire: error 10, "The bit or word indicated cannot be modified" (Error
// reply). The rows the manual answers otherwise (read-only data ignored, 8000h don't care, a
// wrong key) are listed too, so the table shows where 10 is not the answer.
#include <gtest/gtest.h>

#include <functional>

#include "ac20_test_support.hpp"

namespace loopwire::device {
namespace {

using namespace testing;
using namespace ac20_testing;

enum class Mode {
    local,                // power-up: control mode, local (Note 5)
    local_configuration,  // configuration mode, then bit 218 cleared
    local_security,       // security code mode, then bit 218 cleared
    control,              // control mode, remote, factory combinations 0 (nothing locked)
    control_locked,       // control combination 1 (word 4001)
    control_key,          // control combination 77, group 1 (set points) protected, 349 not written
    configuration,        // configuration mode, remote
    security,             // security code mode, remote
    configuration_locked  // configuration combination 1 (word 4000), control mode, remote
};

void reach(Simulated& dev, Mode mode) {
    switch (mode) {
        case Mode::local: return;
        case Mode::local_configuration:
            enter_configuration(dev);
            ASSERT_EQ(set_bit(dev, 218, false), echo_bit(218, false));
            return;
        case Mode::local_security:
            enter_security(dev);
            ASSERT_EQ(set_bit(dev, 218, false), echo_bit(218, false));
            return;
        case Mode::control: go_remote(dev); return;
        case Mode::control_locked:
            enter_security(dev);
            ASSERT_EQ(dev.write(4001, 1), echo_word(4001, 1));
            leave_to_control(dev);
            return;
        case Mode::control_key:
            enter_security(dev);
            ASSERT_EQ(dev.write(4001, 77), echo_word(4001, 77));
            ASSERT_EQ(dev.write(4003, 1), echo_word(4003, 1));
            leave_to_control(dev);
            return;
        case Mode::configuration: enter_configuration(dev); return;
        case Mode::security: enter_security(dev); return;
        case Mode::configuration_locked:
            enter_security(dev);
            ASSERT_EQ(dev.write(4000, 1), echo_word(4000, 1));
            leave_to_control(dev);
            return;
    }
}

struct Row {
    Mode mode;
    std::uint8_t function;  // 5, 6 or 16
    std::uint16_t address;
    std::uint16_t value;
    int expected;  // exception code, or 0 for the normal reply (the write echoed)
    const char* manual;
};

codec::Request request_of(const Row& row) {
    if (row.function == 5) return codec::write_single_coil(row.address, row.value != 0);
    if (row.function == 16) return codec::write_multiple_registers(row.address, {row.value});
    return codec::write_single_register(row.address, row.value);
}

std::string expected_reply(const Row& row) {
    if (row.expected == 0) return echo_of(request_of(row));
    return to_hex(Bytes{static_cast<std::uint8_t>(row.function | 0x80), static_cast<std::uint8_t>(row.expected)});
}

constexpr int refused = 10;  // "The bit or word indicated cannot be modified"
constexpr int accepted = 0;

const char* const note5 = "Note 5: Local mode: \"without possibility of modifying any parameter from the master itself "
                          "(with the exception of the local/remote status bit)\"";
const char* const note6 = "Note 6: \"All the addresses are available only if the device is in control mode, in remote "
                          "mode, in unlock condition (see note 9) and if they are meaningful in the present contest\"";
const char* const note7 = "Note 7: configuration parameters \"are available as writing only if the device is in "
                          "configuration mode\"";
const char* const note8 = "Note 8: security code parameters \"are available as writing only if the device is in security "
                          "code mode\"";
const char* const nb_one = "N.B.: \"Safety lock combination = 1: No security code (all parameters cannot be modified). If "
                           "safety lock combination is for control mode, ModBus word 4002-4011 are forced to 1.\"";
const char* const nb_key = "N.B.: \"Safety lock combination=2-250 ... In order to remove the protection for the control mode "
                           "parameters, it is necessary to write the safety lock combination value for control mode at "
                           "ModBus word 349.\"";
const char* const note8_star = "Note 8 footnote: \"If the value of safety lock combination for configuration mode is 0, all "
                               "values will be accepted. If the value is 1, no value will be accepted.\"";

const Row rows[] = {
    // Note 5: local, whatever the mode.
    {Mode::local, 6, 138, 90, refused, note5},             // SP, a control parameter
    {Mode::local, 16, 138, 90, refused, note5},
    {Mode::local, 6, 137, 90, refused, note5},             // operative set point, a variable
    {Mode::local, 5, 219, 1, refused, note5},              // auto/manual
    {Mode::local, 5, 223, 1, refused, note5},              // load control defaults
    {Mode::local, 6, 347, 0, refused, note5},              // enter configuration mode
    {Mode::local, 6, 348, 0, refused, note5},              // enter security code mode
    {Mode::local, 6, 349, 0, refused, note5},              // control key
    {Mode::local, 5, 218, 1, accepted, note5},             // the local/remote bit itself
    {Mode::local_configuration, 6, 2000, 1, refused, note5},
    {Mode::local_configuration, 6, 3051, 1, refused, note5},
    {Mode::local_configuration, 5, 218, 1, accepted, note5},
    {Mode::local_security, 6, 4001, 5, refused, note5},
    {Mode::local_security, 6, 3051, 1, refused, note5},
    // Notes 6-8: control mode, remote, nothing locked.
    {Mode::control, 6, 2000, 1, refused, note7},           // line frequency, Menu conf. 1
    {Mode::control, 6, 3000, 1, refused, note7},           // end of configuration menu 1
    {Mode::control, 6, 3051, 1, refused, note7},           // back to control mode: a configuration/security word
    {Mode::control, 6, 4001, 5, refused, note8},           // control combination
    {Mode::control, 6, 4003, 1, refused, note8},           // protection of group 1
    {Mode::control, 6, 138, 90, accepted, note6},
    {Mode::control, 6, 130, 250, refused, note6},          // main output value: meaningful in manual only
    {Mode::control, 6, 131, 250, refused, note6},          // secondary output value: no secondary output
    // N.B.: control combination 1.
    {Mode::control_locked, 6, 138, 90, refused, nb_one},   // group 1 St.Pn
    {Mode::control_locked, 6, 177, 150, refused, nb_one},  // group 3 Alrm
    {Mode::control_locked, 6, 1200, 10, refused, nb_one},  // hidden group Hidn
    {Mode::control_locked, 5, 310, 1, refused, nb_one},    // group 9, auxiliary outputs
    {Mode::control_locked, 6, 349, 1, accepted, nb_one},   // 349 stays writable: it is the unlock
    {Mode::control_locked, 6, 137, 90, accepted, note6},   // a variable, not a parameter (menu group)
    // N.B.: control combination 2-250, group 1 protected, 349 not written.
    {Mode::control_key, 6, 138, 90, refused, nb_key},
    {Mode::control_key, 6, 141, 90, refused, nb_key},
    {Mode::control_key, 6, 177, 150, accepted, nb_key},    // group 3 not protected
    // Note 6 and 8: configuration mode, remote.
    {Mode::configuration, 6, 138, 90, refused, note6},
    {Mode::configuration, 6, 137, 90, refused, note6},
    {Mode::configuration, 5, 219, 1, refused, note6},
    {Mode::configuration, 5, 223, 1, refused, note6},
    {Mode::configuration, 6, 4000, 5, refused, note8},
    {Mode::configuration, 6, 2000, 1, accepted, note7},
    // Notes 6 and 7: security code mode, remote.
    {Mode::security, 6, 138, 90, refused, note6},
    {Mode::security, 5, 219, 1, refused, note6},
    {Mode::security, 6, 2000, 1, refused, note7},
    {Mode::security, 6, 3000, 1, refused, note7},
    {Mode::security, 6, 4001, 5, accepted, note8},
    // Note 8 footnote: configuration combination 1.
    {Mode::configuration_locked, 6, 347, 0, refused, note8_star},
    {Mode::configuration_locked, 6, 348, 1, refused, note8_star},
    {Mode::configuration_locked, 6, 2000, 1, refused, note7},
    // Not error 10: FC16 "The data imposed for read only words will be ignored"; FC6/FC16 "The
    // 8000h value ... should be considered as a don't care value"; a key that is not the
    // combination is an illegal data value (3), the word itself could be modified.
    {Mode::control, 16, 120, 7, accepted, "FC16: \"The data imposed for read only words will be ignored.\""},
    {Mode::control, 5, 210, 0, accepted, "FC15: \"The status imposed for read only bits will be ignored.\""},
    {Mode::local, 6, 138, 0x8000, accepted, "FC6: \"The 8000h value ... the value present in the device at this address will not be modified.\""},
};

// Each row on a device brought to its mode; the reply is the row's code, and a refused write
// left the word as it was.
TEST(Ac20Refusals, EveryCannotBeModifiedRuleAnswersError10_Notes5To9_NB) {
    int index = 0;
    for (const Row& row : rows) {
        SCOPED_TRACE(::testing::Message() << "row " << index++ << ": FC" << int{row.function} << " " << row.address << " = "
                                        << row.value << "; " << row.manual);
        Simulated dev("ac20");
        reach(dev, row.mode);
        if (::testing::Test::HasFatalFailure()) return;
        const bool bit = row.function == 5;
        const auto before = bit ? std::uint16_t{dev.bit(row.address)} : dev.word(row.address);
        EXPECT_EQ(dev.send(request_of(row)), expected_reply(row));
        if (row.expected != accepted) {
            EXPECT_EQ(bit ? std::uint16_t{dev.bit(row.address)} : dev.word(row.address), before) << "unchanged";
        }
    }
}

// Error 10 for a block too (FC16 "At the first error found, the command will be aborted"): with
// group 1 protected, a write of SP-SP4 (138-141) is refused at its first word and nothing is
// written.
TEST(Ac20Refusals, ABlockIntoALockedGroupIsRefusedAtItsFirstWord_NB_FC16) {
    Simulated dev("ac20");
    reach(dev, Mode::control_key);
    EXPECT_EQ(dev.send(codec::write_multiple_registers(138, {90, 91, 92, 93})), "90 0A");
    EXPECT_EQ(dev.read(138, 4), Words({80, 80, 80, 80}));
}

}  // namespace
}  // namespace loopwire::device
