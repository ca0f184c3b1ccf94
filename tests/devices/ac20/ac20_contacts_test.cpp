// AC20 external contacts DIG1-DIG3 (Menu conf. 5 "In.Ot.", words 2400-2405, bits 200-202) and
// the set point they select (words 136-141), through the wire. Contacts are closed with the
// faults dig1-closed .. dig3-closed.
#include <gtest/gtest.h>

#include "ac20_test_support.hpp"

namespace loopwire::device {
namespace {

using namespace testing;
using namespace ac20_testing;

// Configuration mode, DIG1 and DIG2 given the functions of word 2400 "1 = Input contact used
// for SP/SP2 auxiliary set point selection 2 = Input contact used for SP3/SP4 auxiliary set point
// selection", back to control mode, and SP 0.80, SP2 0.90, SP3 1.00, SP4 1.10 %C.
void configure_set_point_contacts(Simulated& dev, std::uint16_t dig1_function, std::uint16_t dig2_function) {
    enter_configuration(dev);
    ASSERT_EQ(dev.write(2400, dig1_function), echo_word(2400, dig1_function));
    ASSERT_EQ(dev.write(2402, dig2_function), echo_word(2402, dig2_function));
    ASSERT_EQ(dev.write(3004, 1), echo_word(3004, 1)) << "end of Menu conf. 5: congruent";
    leave_to_control(dev);
    ASSERT_EQ(dev.write(139, 90), echo_word(139, 90));
    ASSERT_EQ(dev.write(140, 100), echo_word(140, 100));
    ASSERT_EQ(dev.write(141, 110), echo_word(141, 110));
}

void close_contact(Simulated& dev, const char* fault) { ASSERT_TRUE(dev.device().inject_fault(fault).ok()); }

// Words 2400/2402 with 1 (SP/SP2) on DIG1 and 2 (SP3/SP4) on DIG2: the two contacts select SP,
// SP2, SP3, SP4 (choice in profiles/NOTES.md); word 136 "Type of operative set point" reads
// "1 = Main set point 2 = Auxiliary set point 2 3 = Auxiliary set point 3 4 = Auxiliary set
// point 4" and word 137 the value in use (factory gradients 7FFFh: a step).
TEST(Ac20Contacts, TwoContactsSelectSpSp2Sp3Sp4_Words2400To2403_Words136And137) {
    Simulated dev("ac20");
    configure_set_point_contacts(dev, 1, 2);
    EXPECT_EQ(dev.word(136), 1);
    EXPECT_EQ(dev.word(137), 80);
    EXPECT_FALSE(dev.bit(200));

    close_contact(dev, "dig1-closed");
    poll(dev, 0.2, 0.1);
    EXPECT_TRUE(dev.bit(200)) << "word 2401 factory 1: logic level 1 when the contact is closed";
    EXPECT_EQ(dev.word(136), 2);
    EXPECT_EQ(dev.word(137), 90);

    close_contact(dev, "dig2-closed");
    poll(dev, 0.2, 0.1);
    EXPECT_TRUE(dev.bit(201));
    EXPECT_EQ(dev.word(136), 4);
    EXPECT_EQ(dev.word(137), 110);

    close_contact(dev, "none");
    close_contact(dev, "dig2-closed");
    poll(dev, 0.2, 0.1);
    EXPECT_FALSE(dev.bit(200));
    EXPECT_EQ(dev.word(136), 3);
    EXPECT_EQ(dev.word(137), 100);
}

// Word 2401 "0 = The input is at logic level "1" when contact is open": an open contact then
// selects SP2, and bit 200 shows the logic level, not the contact.
TEST(Ac20Contacts, LogicLevelWordInvertsTheContact_Words2401_Bit200) {
    Simulated dev("ac20");
    configure_set_point_contacts(dev, 1, 0);
    EXPECT_EQ(dev.word(136), 1);
    enter_configuration(dev);
    ASSERT_EQ(dev.write(2401, 0), echo_word(2401, 0));
    leave_to_control(dev);
    EXPECT_TRUE(dev.bit(200)) << "open contact, logic level 1";
    EXPECT_EQ(dev.word(136), 2);
    EXPECT_EQ(dev.word(137), 90);
    close_contact(dev, "dig1-closed");
    EXPECT_FALSE(dev.bit(200));
    EXPECT_EQ(dev.word(136), 1);
}

// Contacts with no set point function (word 2400 = 0, the factory value; DIG3 has no function
// word) leave the main set point in use.
TEST(Ac20Contacts, ContactsWithoutTheFunctionSelectNothing_Word2400) {
    Simulated dev("ac20");
    go_remote(dev);
    close_contact(dev, "dig1-closed");
    close_contact(dev, "dig3-closed");
    EXPECT_TRUE(dev.bit(200));
    EXPECT_TRUE(dev.bit(202));
    EXPECT_EQ(dev.word(136), 1);
    EXPECT_EQ(dev.word(137), 80);
}

// The process follows the selected set point: SP4 = 1.10 %C selected by both contacts, the
// carbon potential (word 123) settles there.
TEST(Ac20Contacts, TheProcessFollowsTheSelectedSetPoint_Word123_ClosedLoop) {
    Simulated dev("ac20", Model::behaviour, at_speed(100));
    configure_set_point_contacts(dev, 1, 2);
    close_contact(dev, "dig1-closed");
    close_contact(dev, "dig2-closed");
    poll(dev, 15.0);
    EXPECT_EQ(dev.word(136), 4);
    EXPECT_NEAR(static_cast<std::int16_t>(dev.word(123)), 110, 2);
}

// A value written to word 137 (136 = 0) is replaced when a contact changes the selection: the
// contact is the newer command.
TEST(Ac20Contacts, AContactChangeEndsASerialOperativeSetPoint_Words136And137) {
    Simulated dev("ac20");
    configure_set_point_contacts(dev, 1, 2);
    ASSERT_EQ(dev.write(137, 120), echo_word(137, 120));
    EXPECT_EQ(dev.word(136), 0);
    poll(dev, 0.5, 0.1);
    EXPECT_EQ(dev.word(137), 120) << "no change of the contacts: the serial value stays";
    close_contact(dev, "dig2-closed");
    poll(dev, 0.2, 0.1);
    EXPECT_EQ(dev.word(136), 3);
    EXPECT_EQ(dev.word(137), 100);
}

}  // namespace
}  // namespace loopwire::device
