// The manuals' example exchanges (tests/codec/data/manual-example-frames.json) replayed against
// the behaviour models: each example request is decoded with its framing, answered by the
// simulator in the state the example presumes, and the reply is framed again and compared
// byte for byte with the manual's printed reply. Where AUDIT.md §1 found that an example breaks
// a rule, the rule's reply is asserted instead, and the test says so.
#include <gtest/gtest.h>

#include "codec/pdu.hpp"
#include "codec/rtu.hpp"
#include "devices/manual_exchange_support.hpp"

namespace loopwire::device::testing {
namespace {

std::string write_bit(Simulated& device, std::uint16_t bit, bool on) {
    return device.send(codec::write_single_coil(bit, on));
}

// --- AC20 (ENG. 824E rev. 1; both editions print the same frames) -----------------------------
//
// AUDIT.md §1 "AC20": the examples make sense only with J-BUS numbering (wire address = table
// address + 1), so every AC20 replay first selects J-BUS through word 526 = 2 (Modbus numbering,
// in remote and control mode). Under J-BUS, table bit 218 (local/remote) is wire bit 219.
constexpr std::uint16_t jbus = 1;

Simulated ac20_in_jbus_remote() {
    Simulated device("ac20");
    EXPECT_EQ(write_bit(device, 218, true), echo_of(codec::write_single_coil(218, true))) << "remote, Note 5";
    EXPECT_EQ(device.write(526, 2), echo_of(codec::write_single_register(526, 2))) << "S.L.Pr = Jbus";
    EXPECT_EQ(device.word(526 + jbus), 2) << "J-BUS numbering now in force";
    return device;
}

const char* const editions[] = {"en", "ko"};

std::string ac20(const char* edition, const std::string& frame) { return std::string("ac20-") + edition + "-" + frame; }

// "Function code 5: Single bit writing / Example": wire bit 219 is table bit 218, local/remote,
// the one bit writable in local (Note 5). Replayed from local, the echo comes back and the
// device is in remote.
TEST(ManualExchanges, Ac20_FunctionCode5_SingleBitWriting_Example) {
    for (const char* edition : editions) {
        Simulated device = ac20_in_jbus_remote();
        ASSERT_EQ(write_bit(device, 218 + jbus, false), echo_of(codec::write_single_coil(218 + jbus, false)));
        ASSERT_FALSE(device.bit(218 + jbus)) << "local before the example";
        EXPECT_EQ(replay(device, ac20(edition, "fc05-req")), printed(ac20(edition, "fc05-rep"))) << edition;
        EXPECT_TRUE(device.bit(218 + jbus)) << edition;
    }
}

// "Function code 3 and 4: Words reading / Example": wire 178..180 are AL1..AL3 (table 177..179),
// preset through the wire to the printed -100 and 1370. The printed 8000h for AL2 means "not
// relevant in the actual configuration"; the documents give no configuration in which an alarm
// threshold is not relevant, so the model answers AL2 as written: the expected reply is the
// manual's with AL2 = 40 (preset) and its CRC recomputed.
TEST(ManualExchanges, Ac20_FunctionCode3And4_WordsReading_Example) {
    for (const char* edition : editions) {
        Simulated device = ac20_in_jbus_remote();
        ASSERT_EQ(device.write(177 + jbus, raw(-100)), echo_of(codec::write_single_register(177 + jbus, raw(-100))));
        ASSERT_EQ(device.write(178 + jbus, 40), echo_of(codec::write_single_register(178 + jbus, 40)));
        ASSERT_EQ(device.write(179 + jbus, 1370), echo_of(codec::write_single_register(179 + jbus, 1370)));
        Bytes expected = wire_of(example(ac20(edition, "fc03-rep")));
        ASSERT_EQ(expected.size(), 11u);
        expected[5] = 0x00;
        expected[6] = 0x28;
        expected.resize(9);
        expected = codec::rtu_encode(expected[0], ByteView(expected).subspan(1));
        EXPECT_EQ(replay(device, ac20(edition, "fc03-req")), to_hex(expected)) << edition;
    }
}

// "Function code 16: Multiple words writing / Example": wire 139..141 are SP, SP2, SP3 (table
// 138..140). The set points are bounded by rL/rH (words 1011/1012), which the primary variable's
// span (word 2001, carbon potential 0.00-2.00 %C, raw 0-200) limits; the printed 300 (3.00 %C)
// lies above it. A stated rule beats an example (AUDIT.md §1, "AC20"): the reply is exception 3
// (Error reply, code 3 "Illegal data value"), and under the in-order block writes of the AC20
// nothing is stored, since the first word already fails.
TEST(ManualExchanges, Ac20_FunctionCode16_MultipleWordsWriting_Example_RuleWinsSetPointAboveLimit) {
    for (const char* edition : editions) {
        Simulated device = ac20_in_jbus_remote();
        ASSERT_LT(device.word(1012 + jbus), 300) << "rH below the printed SP";
        const Words before = device.read(138 + jbus, 3);
        EXPECT_EQ(replay(device, ac20(edition, "fc16-req")), to_hex(codec::rtu_encode(0x0A, Bytes{0x90, 0x03})))
            << edition;
        EXPECT_EQ(device.read(138 + jbus, 3), before) << edition;
    }
}

// The same example in a configuration where its values are set points: primary variable probe
// mV (word 2001 = 2, configuration mode, Note 7; span 0-1500 mV) and rH (word 1012) = 1500.
// Then 300 and 700 are stored, the printed 8000h leaves SP2 as it was ("don't care"), and the
// reply is the manual's byte for byte.
TEST(ManualExchanges, Ac20_FunctionCode16_MultipleWordsWriting_Example_WithMillivoltSetPoints) {
    for (const char* edition : editions) {
        Simulated device = ac20_in_jbus_remote();
        ASSERT_EQ(device.write(347 + jbus, 0), echo_of(codec::write_single_register(347 + jbus, 0)));
        ASSERT_EQ(device.write(2001 + jbus, 2), echo_of(codec::write_single_register(2001 + jbus, 2)));
        ASSERT_EQ(device.write(3051 + jbus, 1), echo_of(codec::write_single_register(3051 + jbus, 1)));
        ASSERT_EQ(device.write(1012 + jbus, 1500), echo_of(codec::write_single_register(1012 + jbus, 1500)));
        const std::uint16_t sp2_before = device.word(139 + jbus);
        EXPECT_EQ(replay(device, ac20(edition, "fc16-req")), printed(ac20(edition, "fc16-rep"))) << edition;
        EXPECT_EQ(device.read(138 + jbus, 3), (Words{300, sp2_before, 700})) << edition;
    }
}

// "Function code 15: Multiple bits writing / Example": wire 224..232 are table 223..231, the
// load-defaults bits (control mode, Smart off). The printed 0 falls on table bit 226, which
// neither edition lists (group 2 has no defaults). AUDIT.md §1 "AC20": under J-BUS the example
// writes the one undefined bit. The Error reply code 2 "Illegal data address" is the rule for an
// address the tables do not list, and AC20 block writes stop at the first failing address
// (profile block_writes "in-order"), so the reply is exception 2, not the printed echo.
TEST(ManualExchanges, Ac20_FunctionCode15_MultipleBitsWriting_Example_RuleWinsUndefinedBitIsException2) {
    for (const char* edition : editions) {
        Simulated device = ac20_in_jbus_remote();
        EXPECT_EQ(replay(device, ac20(edition, "fc15-req")), to_hex(codec::rtu_encode(0x02, Bytes{0x8F, 0x02})))
            << edition;
        // Without the undefined bit (wire 224..226 = table 223..225) the write is echoed.
        const auto defined = codec::write_multiple_coils(224, {0, 1, 1});
        EXPECT_EQ(device.send(defined), echo_of(defined)) << edition;
    }
}

// "Function code 6: Single word writing / Example": wire 2006 is table 2005, tP.FL, writable in
// configuration mode (Note 7), entered through table word 347 (wire 348) from remote.
TEST(ManualExchanges, Ac20_FunctionCode6_SingleWordWriting_Example) {
    for (const char* edition : editions) {
        Simulated device = ac20_in_jbus_remote();
        ASSERT_EQ(device.write(347 + jbus, 0), echo_of(codec::write_single_register(347 + jbus, 0)));
        EXPECT_EQ(replay(device, ac20(edition, "fc06-req")), printed(ac20(edition, "fc06-rep"))) << edition;
        EXPECT_EQ(device.word(2005 + jbus), 1250) << edition;
    }
}

// "Function code 1 and 2: Bits reading / Example": wire 201..214 are table 200..213, the digital
// inputs, alarm relays and status bits: live values of the process and the wiring, so the
// printed A7h 04h cannot be reproduced as a whole. What the rules fix is asserted: a normal
// reply of 2 bytes for 14 bits, the change flag (table 210) set at start-up, tune, adaptive and
// lock (211..213) clear on a fresh device, and the 2 padding bits 0.
TEST(ManualExchanges, Ac20_FunctionCode1And2_BitsReading_Example) {
    for (const char* edition : editions) {
        Simulated device = ac20_in_jbus_remote();
        const std::string reply = replay(device, ac20(edition, "fc01-req"));
        const Bytes bytes = parse_hex(reply).value_or(Bytes{});
        ASSERT_EQ(bytes.size(), 7u) << reply;
        EXPECT_EQ(bytes[0], 0x64);
        EXPECT_EQ(bytes[1], 0x01);
        EXPECT_EQ(bytes[2], 0x02);
        EXPECT_EQ(bytes[4] & 0x3C, 0x04) << "bits 210..213 = 1,0,0,0 and padding 0: " << reply;
        EXPECT_EQ(bytes[4] & 0xC0, 0x00);
    }
}

// --- TC10 (tc10-modbus-im05c01e81-03.ru.txt) ---------------------------------------------------

// §3.1 "Функциональный код 3 / Пример": registers 25 and 26 are read-only (quick-configuration
// code 2 and a reserved word), so the printed 10 and 20 cannot be preset through the wire. The
// framing, function, byte count and a normal reply are asserted; the words are what the
// device's own reads of 25 and 26 give.
TEST(ManualExchanges, Tc10_3_1_FunctionCode3_Example) {
    Simulated device("tc10");
    const Words held = device.read(25, 2);
    ASSERT_EQ(held.size(), 2u);
    Bytes expected{0x01, 0x03, 0x04};
    append_be16(expected, held[0]);
    append_be16(expected, held[1]);
    expected = codec::rtu_encode(0x01, ByteView(expected).subspan(1));
    EXPECT_EQ(replay(device, "tc10-fc03-req"), to_hex(expected));
}

// §3.2 "Функциональный код 6 / Пример" writes 10 to 770 (bAud, range 0..4). AUDIT.md §1,
// "Semantic problems", TC10 FC6: rule 4.4 B.2 (out-of-range writes are refused) wins over the
// printed echo, so the reply is exception 3 and the register keeps its value.
TEST(ManualExchanges, Tc10_3_2_FunctionCode6_Example_RuleWinsOutOfRangeIsException3) {
    Simulated device("tc10");
    const std::uint16_t before = device.word(770);
    EXPECT_NE(replay(device, "tc10-fc06-req"), printed("tc10-fc06-rep"));
    EXPECT_EQ(replay(device, "tc10-fc06-req"), to_hex(codec::rtu_encode(0x01, Bytes{0x86, 0x03})));
    EXPECT_EQ(device.word(770), before);
    // The same frame with a value inside 0..4 gets the example's echo shape.
    EXPECT_EQ(device.write(770, 4), echo_of(codec::write_single_register(770, 4)));
}

// §3.3 "Функциональный код 16 / Пример" writes 100 to 10314 (nSP, range 1..4). AUDIT.md §1,
// "Semantic problems", TC10 FC16: rule 4.4 B.2 wins, exception 3, nothing written.
TEST(ManualExchanges, Tc10_3_3_FunctionCode16_Example_RuleWinsOutOfRangeIsException3) {
    Simulated device("tc10");
    const Words before = device.read(10314, 2);
    EXPECT_EQ(replay(device, "tc10-fc16-req"), to_hex(codec::rtu_encode(0x01, Bytes{0x90, 0x03})));
    EXPECT_EQ(device.read(10314, 2), before);
}

}  // namespace
}  // namespace loopwire::device::testing
