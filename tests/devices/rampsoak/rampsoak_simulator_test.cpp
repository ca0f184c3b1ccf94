// The rampsoak behaviour model through the wire (manual rampsoak-pid-rtu-ascii-linking.en.txt).
// Values are raw words; with the model's DP = 1 a temperature word is tenths of °C.
#include <cstdint>
#include <string>
#include <variant>

#include <gtest/gtest.h>

#include "session/linking_frame_codec.hpp"
#include "simulation/simulator_harness.hpp"

namespace loopwire::device::testing {
namespace {

// §7 Register Map addresses.
constexpr std::uint16_t sv = 0x0000;
constexpr std::uint16_t outl = 0x0001;
constexpr std::uint16_t al1 = 0x0003;
constexpr std::uint16_t al2 = 0x0004;
constexpr std::uint16_t al3 = 0x0005;
constexpr std::uint16_t ptn = 0x0006;
constexpr std::uint16_t seg = 0x0007;
constexpr std::uint16_t timr = 0x0008;
constexpr std::uint16_t pattern_1 = 0x0009;  // SV_1, TM_1, OUT1, SV_2, ...
constexpr std::uint16_t pattern_2 = 0x0021;
constexpr std::uint16_t p1 = 0x0039;
constexpr std::uint16_t lspl = 0x004C;
constexpr std::uint16_t uspl = 0x004D;
constexpr std::uint16_t ald1 = 0x0050;
constexpr std::uint16_t ald2 = 0x0052;
constexpr std::uint16_t ald3 = 0x0054;
constexpr std::uint16_t psl = 0x0060;
constexpr std::uint16_t bits = 0x0061;
constexpr std::uint16_t idno = 0x0062;
constexpr std::uint16_t baud = 0x0063;
constexpr std::uint16_t pvos = 0x0065;
constexpr std::uint16_t unit = 0x0066;
constexpr std::uint16_t out_percent = 0x0087;
constexpr std::uint16_t obit = 0x0088;
constexpr std::uint16_t pv = 0x008A;

// OBIT bits (§7, 0088H).
constexpr std::uint16_t out1_led = 1u << 0;
constexpr std::uint16_t al1_led = 1u << 3;
constexpr std::uint16_t al2_led = 1u << 4;
constexpr std::uint16_t al3_led = 1u << 5;
constexpr std::uint16_t pro_led = 1u << 6;
constexpr std::uint16_t man_led = 1u << 7;
constexpr std::uint16_t in1e = 1u << 8;

SimulationEnvironment served_over(const std::string& framing, double speed = 1.0) {
    SimulationEnvironment environment;
    environment.framing = framing;
    environment.speed = speed;
    return environment;
}

// At speed 60 one second of the test's clock is one minute of process time, the unit of the
// program's TM_n and TIMR, so the program tests read in minutes.
SimulationEnvironment minutes_per_second() { return served_over("rtu", 60.0); }

// A Linking frame (§6.1) through the slave side of the Linking adapter into the simulator,
// and the simulator's reply back out as Linking bytes; "silence" when nothing is answered.
std::string linking(Simulated& device, const Bytes& frame) {
    auto codec = session::make_linking_frame_codec(codec::Direction::request, false);
    auto events = codec->feed(frame, Instant{});
    if (!events.ok() || events->size() != 1 || !std::holds_alternative<codec::Frame>(events->front())) return "not a frame";
    const auto& request = std::get<codec::Frame>(events->front());
    auto reply = device.device().handle(request.pdu, false);
    if (!reply) return "silence";
    auto wire = codec->encode(request.unit, *reply, 0);
    return wire.ok() ? to_hex(*wire) : "unencodable";
}

bool lit(Simulated& device, std::uint16_t led) { return (device.word(obit) & led) != 0; }
int signed_word(Simulated& device, std::uint16_t address) { return static_cast<std::int16_t>(device.word(address)); }

// --- Persistence: Linking R / M / W (§6.2) --------------------------------------------------

// §6.7.2 and §6.7.3: W writes SV = 100.0 to RAM and EEPROM, M then modifies it to 10.0 in RAM
// only; the device answers 10.0 now and keeps 100.0 for after power off.
TEST(RampSoakSimulator, LinkingModifyChangesRamOnlyAndWriteReachesEeprom_6_2) {
    Simulated device("rampsoak", Model::behaviour, served_over("linking"));
    EXPECT_EQ(linking(device, {0x57, 0x01, 0x00, 0x00, 0x03, 0xE8, 0x43}), "07 4D 01 00 00 03 E8 39");
    EXPECT_EQ(device.device().saved_values().at("set_value"), 1000);
    EXPECT_EQ(linking(device, {0x4D, 0x01, 0x00, 0x00, 0x00, 0x64, 0xB2}), "07 4D 01 00 00 00 64 B2");
    EXPECT_EQ(linking(device, {0x52, 0x01, 0x00, 0x00, 0x00, 0x00, 0x53}), "07 4D 01 00 00 00 64 B2");
    EXPECT_EQ(device.device().saved_values().at("set_value"), 1000);
}

// §6.2: "Data are not maintained after power off" for M, "maintained" for W.
TEST(RampSoakSimulator, OnlyLinkingWriteSurvivesRestart_6_2) {
    Simulated device("rampsoak", Model::behaviour, served_over("linking"));
    linking(device, {0x57, 0x01, 0x00, 0x03, 0x01, 0xF4, 0x50});  // W AL1 = 50.0
    linking(device, {0x4D, 0x01, 0x00, 0x04, 0x00, 0xC8, 0x1A});  // M AL2 = 20.0
    EXPECT_EQ(device.read(al1, 2), (Words{500, 200}));

    Simulated restarted("rampsoak", Model::behaviour, served_over("linking"));
    EXPECT_TRUE(restarted.device().load_saved(device.device().saved_values()).empty());
    EXPECT_EQ(restarted.read(al1, 2), (Words{500, 0}));
}

// §4/§5 do not say where a Modbus write goes; the model saves FC06 and FC10 writes (see
// persistence_of), so on an RTU link FC06 is not the RAM-only M.
TEST(RampSoakSimulator, ModbusWritesAreSavedOnRtuAndAscii_4_3_5_3) {
    for (const std::string framing : {"rtu", "ascii"}) {
        Simulated device("rampsoak", Model::behaviour, served_over(framing));
        EXPECT_EQ(device.write(al1, 500), "06 00 03 01 F4");
        EXPECT_EQ(device.send(codec::write_multiple_registers(al2, {300})), "10 00 04 00 01");
        Simulated restarted("rampsoak", Model::behaviour, served_over(framing));
        restarted.device().load_saved(device.device().saved_values());
        EXPECT_EQ(restarted.read(al1, 2), (Words{500, 300})) << framing;
    }
}

// --- Level 3 settings (§1) ------------------------------------------------------------------

// §1: PSL selects PU (RTU), PACI (ASCII) or PRE (Linking); the device answering on a link is
// set to that link's protocol. On Modbus/TCP, which it does not speak, PSL keeps the default PU.
TEST(RampSoakSimulator, ProtocolSelectionMatchesTheLinkItServes_1) {
    EXPECT_EQ(Simulated("rampsoak", Model::behaviour, served_over("rtu")).word(psl), 0);
    EXPECT_EQ(Simulated("rampsoak", Model::behaviour, served_over("ascii")).word(psl), 1);
    EXPECT_EQ(Simulated("rampsoak", Model::behaviour, served_over("linking")).word(psl), 2);
    EXPECT_EQ(Simulated("rampsoak", Model::behaviour, served_over("tcp")).word(psl), 0);
}

// §1 Level 3 defaults: IDNO 1, BAUD 384 (code 4 = 38400), BITS OB1 (code 0). §7: PSL is 03H
// only, set from the front panel, so a line write is refused (exception 02, §4.6).
TEST(RampSoakSimulator, LevelThreeWordsStartAtTheirDefaultsAndAreReadOnly_1_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("ascii"));
    EXPECT_EQ(device.read(psl, 4), (Words{1, 0, 1, 4}));
    EXPECT_EQ(device.write(psl, 0), "86 02");
    EXPECT_EQ(device.word(psl), 1);
    EXPECT_EQ(device.word(bits), 0);
    EXPECT_EQ(device.word(idno), 1);
    EXPECT_EQ(device.word(baud), 4);
}

// --- The program (§7 rows PTN, SEG, TIMR, SV_n, TM_n, OUTn) ---------------------------------

// Pattern 1: ramp to 200.0 in 10 min, soak 5 min, ramp down to 100.0 in 5 min, TM_4 = 0 ends it.
void load_ramp_soak_ramp(Simulated& device) {
    ASSERT_EQ(device.send(codec::write_multiple_registers(pattern_1, {2000, 10, 1000, 2000, 5, 1000, 1000, 5})),
              "10 00 09 00 08");
}

// The working set point (read at SV) ramps from the PV at the start, soaks and ramps per
// segment; SEG counts segments and TIMR the minutes left in the segment, rounded up.
TEST(RampSoakSimulator, ProgramSetPointFollowsTheSegments_7) {
    Simulated device("rampsoak", Model::behaviour, minutes_per_second());
    load_ramp_soak_ramp(device);
    const int start = signed_word(device, pv);
    EXPECT_EQ(device.write(ptn, 1), "06 00 06 00 01");
    EXPECT_EQ(device.read(seg, 2), (Words{1, 10}));
    EXPECT_NEAR(signed_word(device, sv), start, 2);

    device.wait(5.5);  // 5.5 min into the 10 min ramp
    EXPECT_EQ(device.read(seg, 2), (Words{1, 5}));
    EXPECT_NEAR(signed_word(device, sv), start + (2000 - start) * 0.55, 2);

    device.wait(7.0);  // 12.5 min: soaking in segment 2, 2.5 min left
    EXPECT_EQ(device.read(seg, 2), (Words{2, 3}));
    EXPECT_EQ(device.word(sv), 2000);

    device.wait(4.0);  // 16.5 min: 1.5 min into the 5 min ramp down
    EXPECT_EQ(device.read(seg, 2), (Words{3, 4}));
    EXPECT_NEAR(signed_word(device, sv), 1700, 2);
}

// The program follows the selected pattern: pattern 2 (0021H...) runs its own set points.
TEST(RampSoakSimulator, PatternTwoRunsItsOwnSegments_7) {
    Simulated device("rampsoak", Model::behaviour, minutes_per_second());
    load_ramp_soak_ramp(device);
    ASSERT_EQ(device.send(codec::write_multiple_registers(pattern_2, {600, 2, 1000})), "10 00 21 00 03");
    device.write(ptn, 2);
    device.wait(1.5);
    EXPECT_EQ(device.read(seg, 2), (Words{1, 1}));
    EXPECT_NEAR(signed_word(device, sv), 512, 2);  // three quarters of the way from 25.0 to 60.0
}

// End of the pattern: the program stops (SEG 0, TIMR 0, PRO LED off) and the controller holds
// the last segment's set point, which the PV then settles at.
TEST(RampSoakSimulator, ProgramEndHoldsTheLastSetPoint_7) {
    Simulated device("rampsoak", Model::behaviour, minutes_per_second());
    load_ramp_soak_ramp(device);
    device.write(ptn, 1);
    EXPECT_TRUE(lit(device, pro_led));
    device.wait(21.0);
    EXPECT_EQ(device.read(seg, 2), (Words{0, 0}));
    EXPECT_FALSE(lit(device, pro_led));
    EXPECT_EQ(device.word(sv), 1000);
    device.wait(20.0);
    EXPECT_NEAR(signed_word(device, pv), 1000, 10);
    // Writing PTN again runs the pattern again from segment 1.
    device.write(ptn, 1);
    EXPECT_EQ(device.read(seg, 2), (Words{1, 10}));
    EXPECT_TRUE(lit(device, pro_led));
}

// PTN is a saved setting, but a restart leaves the program stopped (the manual describes no
// power-failure recovery): SEG reads 0 and the controller runs on the fixed SV.
TEST(RampSoakSimulator, RestartLeavesTheProgramStopped_7) {
    Simulated device("rampsoak", Model::behaviour, minutes_per_second());
    device.write(sv, 400);
    load_ramp_soak_ramp(device);
    device.write(ptn, 1);
    device.wait(3.0);
    Simulated restarted("rampsoak", Model::behaviour, minutes_per_second());
    restarted.device().load_saved(device.device().saved_values());
    EXPECT_EQ(restarted.word(ptn), 1);
    EXPECT_EQ(restarted.read(seg, 2), (Words{0, 0}));
    EXPECT_EQ(restarted.word(sv), 400);
    EXPECT_FALSE(lit(restarted, pro_led));
}

// PTN = 0 stops the program: SV reads the fixed set point again and control returns to it.
TEST(RampSoakSimulator, PatternZeroStopsTheProgram_7) {
    Simulated device("rampsoak", Model::behaviour, minutes_per_second());
    device.write(sv, 500);
    load_ramp_soak_ramp(device);
    device.write(ptn, 1);
    device.wait(3.0);
    EXPECT_NE(device.word(sv), 500);
    device.write(ptn, 0);
    EXPECT_EQ(device.read(seg, 2), (Words{0, 0}));
    EXPECT_EQ(device.word(sv), 500);
    EXPECT_FALSE(lit(device, pro_led));
}

// A running segment's OUTn limits the output; OUTL (0001H) limits it too, the lower one wins.
TEST(RampSoakSimulator, SegmentOutputLimitCapsTheOutput_7) {
    Simulated device("rampsoak", Model::behaviour, minutes_per_second());
    // A 2-minute ramp to 800.0: the set point runs far ahead of the PV, the PID asks for full output.
    ASSERT_EQ(device.send(codec::write_multiple_registers(pattern_1, {8000, 2, 300})), "10 00 09 00 03");
    device.write(ptn, 1);
    device.wait(1.0);
    EXPECT_EQ(device.word(out_percent), 300);
    device.write(outl, 200);
    device.wait(0.25);
    EXPECT_EQ(device.word(out_percent), 200);
}

// --- Process: PID (P1, I1, D1), plant, OUT% and the OUT1 LED (§7) ----------------------------

// Closed loop: SV 150.0 from a 25.0 room; after 500 s of process time (5 s at speed 100) the
// PV is within 1.0 °C and the output holds the heat loss (125 of 800 °C: about 15.6 %).
TEST(RampSoakSimulator, ClosedLoopSettlesAtTheSetPoint_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("rtu", 100.0));
    EXPECT_NEAR(signed_word(device, pv), 250, 2);
    device.write(sv, 1500);
    device.wait(0.05);
    EXPECT_EQ(device.word(out_percent), 1000);  // far below SV: full output
    EXPECT_TRUE(lit(device, out1_led));
    device.wait(5.0);
    EXPECT_NEAR(signed_word(device, pv), 1500, 10);
    EXPECT_NEAR(device.word(out_percent), 156, 15);
    EXPECT_TRUE(lit(device, out1_led));
}

// P1 = 0 is on/off control: the output is only ever 0 or 100.0 %.
TEST(RampSoakSimulator, ZeroProportionalBandIsOnOffControl_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("rtu", 100.0));
    device.write(p1, 0);
    device.write(sv, 800);
    bool heated = false;
    bool rested = false;
    for (int i = 0; i < 80; ++i) {
        device.wait(0.25);
        const auto output = device.word(out_percent);
        EXPECT_TRUE(output == 0 || output == 1000) << output;
        heated = heated || output == 1000;
        rested = rested || output == 0;
    }
    EXPECT_TRUE(heated && rested);
    EXPECT_NEAR(signed_word(device, pv), 800, 300);
}

// OUTL = 0 leaves the heater off: the chamber stays at room temperature.
TEST(RampSoakSimulator, ZeroOutputLimitKeepsTheHeaterOff_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("rtu", 100.0));
    device.write(outl, 0);
    device.write(sv, 1500);
    device.wait(5.0);
    EXPECT_EQ(device.word(out_percent), 0);
    EXPECT_FALSE(lit(device, out1_led));
    EXPECT_NEAR(signed_word(device, pv), 250, 2);
}

// Sensor break: OBIT message IN1E (bit 8); the PV word reads 9999 (top of the §7 PV range,
// upscale burn-out) and the output drops to 0. Clearing the fault restores the measurement.
TEST(RampSoakSimulator, OpenInputShowsIn1eAndDrivesPvUpscale_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("rtu", 100.0));
    device.write(sv, 1500);
    device.wait(3.0);
    const int before = signed_word(device, pv);
    ASSERT_TRUE(device.device().inject_fault("open-input").ok());
    EXPECT_EQ(device.word(pv), 9999);
    EXPECT_TRUE(lit(device, in1e));
    device.wait(0.5);
    EXPECT_EQ(device.word(out_percent), 0);
    EXPECT_FALSE(lit(device, out1_led));
    ASSERT_TRUE(device.device().inject_fault("none").ok());
    EXPECT_FALSE(lit(device, in1e));
    EXPECT_LT(signed_word(device, pv), before);  // the chamber cooled while the heater was off
    EXPECT_GT(signed_word(device, pv), 250);
    EXPECT_FALSE(device.device().inject_fault("short-circuit").ok());
}

// --- Alarms: ALDn modes and the AL1-AL3 LEDs of OBIT (§7, 0003H-0005H, 0050H-0054H, 0088H) ---

// Mode 5, process high: AL1 lights once the PV reaches AL1 = 50.0.
TEST(RampSoakSimulator, ProcessHighAlarmFollowsThePv_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("rtu", 100.0));
    device.write(ald1, 5);
    device.write(al1, 500);
    EXPECT_FALSE(lit(device, al1_led));
    device.write(sv, 1000);
    device.wait(10.0);
    EXPECT_TRUE(lit(device, al1_led));
    EXPECT_FALSE(lit(device, al2_led));
}

// Mode 2, deviation low (AL2 = -5.0): on while the PV lags the set point by 5 °C or more, off
// once it has settled. Mode 4, band (AL3 = 2.0): on only inside SV ± 2.0.
TEST(RampSoakSimulator, DeviationAndBandAlarmsFollowTheSetPoint_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("rtu", 100.0));
    device.write(ald2, 2);
    device.write(al2, raw(-50));
    device.write(ald3, 4);
    device.write(al3, 20);
    device.write(sv, 1500);
    device.wait(0.5);
    EXPECT_TRUE(lit(device, al2_led));
    EXPECT_FALSE(lit(device, al3_led));
    device.wait(12.0);
    EXPECT_FALSE(lit(device, al2_led));
    EXPECT_TRUE(lit(device, al3_led));
}

// Mode 7, segment alarm: AL1 = 2 lights while segment 2 runs, and only then.
TEST(RampSoakSimulator, SegmentAlarmLightsDuringItsSegment_7) {
    Simulated device("rampsoak", Model::behaviour, minutes_per_second());
    device.write(ald1, 7);
    device.write(al1, 2);
    load_ramp_soak_ramp(device);
    device.write(ptn, 1);
    EXPECT_FALSE(lit(device, al1_led));
    device.wait(12.0);
    EXPECT_EQ(device.word(seg), 2);
    EXPECT_TRUE(lit(device, al1_led));
    device.wait(4.0);
    EXPECT_EQ(device.word(seg), 3);
    EXPECT_FALSE(lit(device, al1_led));
}

// --- Set point limits, unit and PV compensation (§7 rows 004CH, 004DH, 0065H, 0066H) -------

// §7 LSPL "Lower Set Point Limit" and USPL "Upper Set Point Limit" bound SV and the segment set
// points; a value outside them is §4.6 abnormal code 03, "Data value is out of setting range",
// and is not stored. The factory limits are the whole PV span (-199.9 ... 999.9 at DP = 1).
TEST(RampSoakSimulator, SetPointsOutsideLsplUsplAreOutOfSettingRange_4_6_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("rtu"));
    EXPECT_EQ(device.read(lspl, 2), (Words{raw(-1999), 9999}));
    EXPECT_EQ(device.write(sv, 9000), "06 00 00 23 28");
    EXPECT_EQ(device.send(codec::write_multiple_registers(lspl, {0, 2000})), "10 00 4C 00 02");
    EXPECT_EQ(device.write(sv, 2001), "86 03");
    EXPECT_EQ(device.write(sv, raw(-1)), "86 03");
    EXPECT_EQ(device.word(sv), 9000);  // refused, not stored; a stored SV stays as it was
    EXPECT_EQ(device.write(sv, 2000), "06 00 00 07 D0");
    EXPECT_EQ(device.write(sv, 0), "06 00 00 00 00");
    // The segment set points too (pattern 1 SV_2 and pattern 2 SV_12); FC10 is all or nothing.
    EXPECT_EQ(device.send(codec::write_multiple_registers(pattern_1, {1500, 10, 1000, 2500})), "90 03");
    EXPECT_EQ(device.word(pattern_1), 0);
    EXPECT_EQ(device.write(pattern_2, 2500), "86 03");
    EXPECT_EQ(device.send(codec::write_multiple_registers(pattern_1, {1500, 10, 1000, 2000})), "10 00 09 00 04");
}

// The model's choice (the manual is silent): LSPL may not pass USPL, nor USPL fall under LSPL.
TEST(RampSoakSimulator, LsplAndUsplCannotCross_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("rtu"));
    EXPECT_EQ(device.send(codec::write_multiple_registers(lspl, {1000, 2000})), "10 00 4C 00 02");
    EXPECT_EQ(device.write(lspl, 2001), "86 03");
    EXPECT_EQ(device.write(uspl, 999), "86 03");
    EXPECT_EQ(device.read(lspl, 2), (Words{1000, 2000}));
    EXPECT_EQ(device.write(lspl, 2000), "06 00 4C 07 D0");  // equal limits: one set point allowed
}

// §7 UNIT "Unit of PV and SV", 0001H = F: the PV reads in °F (a 25.0 °C room is 77.0 °F) and
// SV is taken in °F: SV 302.0 °F settles there, and back in C the same chamber reads 150.0 °C.
// (P1 keeps its number, so in °F the loop is 1.8 times tighter and hunts a little: the PV is
// checked to 2.0 °F.)
TEST(RampSoakSimulator, UnitFahrenheitReadsPvAndTakesSvInFahrenheit_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("rtu", 100.0));
    EXPECT_NEAR(signed_word(device, pv), 250, 2);
    EXPECT_EQ(device.write(unit, 1), "06 00 66 00 01");
    EXPECT_NEAR(signed_word(device, pv), 770, 2);
    device.write(sv, 3020);
    device.wait(15.0);
    EXPECT_NEAR(signed_word(device, pv), 3020, 20);
    // Back to C: the same chamber reads in °C again; SV keeps its number (not converted).
    EXPECT_EQ(device.write(unit, 0), "06 00 66 00 00");
    EXPECT_NEAR(signed_word(device, pv), 1500, 12);
    EXPECT_EQ(device.word(sv), 3020);
}

// §7 PVOS "PV Compensation": the PV word reads the measurement plus PVOS, and the controller
// controls that compensated PV: with PVOS = -50.0 and SV = 150.0 the chamber settles at
// 200.0 °C, which takes about 21.9 % output (175 of 800 °C) instead of 15.6 %.
TEST(RampSoakSimulator, PvCompensationOffsetsThePvTheControllerControls_7) {
    Simulated device("rampsoak", Model::behaviour, served_over("rtu", 100.0));
    EXPECT_EQ(device.write(pvos, raw(-500)), "06 00 65 FE 0C");
    EXPECT_NEAR(signed_word(device, pv), -250, 2);
    device.write(sv, 1500);
    device.wait(6.0);
    EXPECT_NEAR(signed_word(device, pv), 1500, 10);
    EXPECT_NEAR(device.word(out_percent), 219, 15);
    device.write(pvos, 0);
    EXPECT_NEAR(signed_word(device, pv), 2000, 15);
}

// --- Hold and manual: out of reach over the line (§7) -----------------------------------------

// §7 lists no hold, run/stop or auto/manual register; OUT% (0087H), the only output word, is
// 03H (read-only), so the output cannot be set by hand: a write is refused with §4.6 code 02
// and the MAN LED (OBIT bit 7) stays off while the controller runs its program.
TEST(RampSoakSimulator, NoRegisterReachesManualOutputOrHold_4_6_7) {
    Simulated device("rampsoak", Model::behaviour, minutes_per_second());
    EXPECT_EQ(device.write(out_percent, 500), "86 02");
    load_ramp_soak_ramp(device);
    device.write(ptn, 1);
    device.wait(1.5);
    EXPECT_FALSE(lit(device, man_led));
    EXPECT_EQ(device.read(seg, 2), (Words{1, 9}));  // the segment timer runs on
}

}  // namespace
}  // namespace loopwire::device::testing
