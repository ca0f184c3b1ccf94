// The external contacts DIG1-DIG3 (Menu conf. 5 "In.Ot.", words 2400-2405; bits 200-202) and
// the set point they select (SP, SP2, SP3, SP4: words 138-141; word 136).
//
// The simulator's contacts are open until a --fault closes one: "dig1-closed", "dig2-closed",
// "dig3-closed" ("none" opens them again with the other faults).
#include <array>
#include <string>

#include "devices/ac20/ac20_simulator.hpp"

namespace loopwire::device::models {
namespace {

// Word 2400 "External contact "DIG1" function": "1 = Input contact used for SP/SP2 auxiliary
// set point selection 2 = Input contact used for SP3/SP4 auxiliary set point selection".
constexpr std::uint16_t selects_sp_sp2 = 1;
constexpr std::uint16_t selects_sp3_sp4 = 2;

struct Contact {
    const char* fault;
    const char* level_bit;      // bits 200-202 "Logic level of external contact DigN"
    const char* function_word;  // nullptr: DIG3 has no function word (2404 is not listed)
    const char* polarity_word;
};
constexpr std::array<Contact, 3> contacts{{
    {"dig1-closed", "dig1_logic_level", "dig1_function", "dig1_polarity"},
    {"dig2-closed", "dig2_logic_level", "dig2_function", "dig2_polarity"},
    {"dig3-closed", "dig3_logic_level", nullptr, "dig3_polarity"},
}};

}  // namespace

// Word 2401 "External contact "DIG1" logic level": "0 = The input is at logic level "1" when
// contact is open 1 = The input is at logic level "1" when contact is closed" (2403, 2405 the
// same for DIG2, DIG3).
bool Ac20Simulator::contact_level(std::size_t index) const {
    const Contact& contact = contacts.at(index);
    const bool closed = fault(contact.fault);
    return value(contact.polarity_word) == 1 ? closed : !closed;
}

// Which set point the contacts select, as word 136 numbers them (1 = SP .. 4 = SP4). The
// manual names the two functions but not how they combine; the choice (profiles/NOTES.md): an
// "SP3/SP4" input at logic level 1 selects the pair SP3/SP4 instead of SP/SP2, and an "SP/SP2"
// input at logic level 1 selects the second of the pair. So with both functions configured the
// two inputs select SP (0, 0), SP2 (1, 0), SP3 (0, 1), SP4 (1, 1); with the SP/SP2 function
// alone, SP or SP2; with the SP3/SP4 function alone, SP or SP3. No input so configured: SP.
int Ac20Simulator::selected_set_point() const {
    bool second = false, pair_3_4 = false;
    for (std::size_t index = 0; index < contacts.size(); ++index) {
        if (contacts[index].function_word == nullptr || !contact_level(index)) continue;
        const std::uint16_t function = value(contacts[index].function_word);
        second = second || function == selects_sp_sp2;
        pair_3_4 = pair_3_4 || function == selects_sp3_sp4;
    }
    return (pair_3_4 ? 3 : 1) + (second ? 1 : 0);
}

std::uint16_t Ac20Simulator::set_point_word(int type) const {
    switch (type) {
        case 2: return value("auxiliary_set_point_2");
        case 3: return value("auxiliary_set_point_3");
        case 4: return value("auxiliary_set_point_4");
        default: return value("main_set_point");
    }
}

// Bits 200-202 show the contacts' logic levels. A change of the selection makes the selected set
// point operative (word 136 = 1..4), also over a value written to word 137 (type 0): the
// contact is the newer command.
void Ac20Simulator::follow_contacts() {
    for (std::size_t index = 0; index < contacts.size(); ++index) {
        set_value(contacts[index].level_bit, contact_level(index) ? 1 : 0);
    }
    const int selected = selected_set_point();
    if (selected != last_selection_ || operative_set_point_type_ != 0) operative_set_point_type_ = selected;
    last_selection_ = selected;
}

}  // namespace loopwire::device::models
