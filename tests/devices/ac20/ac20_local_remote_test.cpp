// AC20 Note 5 (local/remote status) across a power-off (the --state file) and on a shared line
// (frames for other slaves are line activity), through the wire.
#include <gtest/gtest.h>

#include <stdlib.h>

#include <filesystem>
#include <fstream>

#include "codec/rtu.hpp"
#include "devices/registry.hpp"
#include "session/slave.hpp"
#include "simulation/state_file.hpp"
#include "support/test_bytes.hpp"
#include "support/virtual_line.hpp"
#include "ac20_test_support.hpp"

namespace loopwire::device {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using namespace testing;
using namespace ac20_testing;
using loopwire::testing::hex;

// --- Note 5: power-up after a power-off, through the --state file -----------------------------

class Ac20PowerUp : public ::testing::Test {
protected:
    void SetUp() override {
        std::string pattern = (fs::temp_directory_path() / "loopwire-ac20-state-XXXXXX").string();
        ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
        dir = pattern;
        path = (dir / "state.json").string();
    }
    void TearDown() override { fs::remove_all(dir); }

    // Saves `dev` as unit 3 (a running simulator saving its state), then "switches off".
    void power_off(Simulated& dev) {
        auto state = SimulatorStateFile::open(path, {{3, std::shared_ptr<SimulatedDevice>(&dev.device(), [](SimulatedDevice*) {})}});
        ASSERT_TRUE(state) << state.error().message;
        // The mode was entered before the file was opened: the file is written as it is now.
        ASSERT_TRUE(state->save_if_changed());
        ASSERT_FALSE(state->has_unsaved_changes());
    }
    // A new simulator for unit 3 loading the file, as `loopwire simulate --state` does.
    void power_on(Simulated& dev) {
        auto state = SimulatorStateFile::open(path, {{3, std::shared_ptr<SimulatedDevice>(&dev.device(), [](SimulatedDevice*) {})}});
        ASSERT_TRUE(state) << state.error().message;
        EXPECT_TRUE(state->warnings().empty());
    }
    std::string file_text() const {
        std::ifstream file(path);
        return std::string(std::istreambuf_iterator<char>(file), {});
    }

    fs::path dir;
    std::string path;
};

// Note 5: "At power up, the slave will be in local mode if it was in control mode at power off.
// In the other cases, it will maintain the condition it was at the power off." Configuration
// mode in remote comes back in configuration mode (word 135 = 6) and in remote (bit 218), so a
// configuration word is still writable.
TEST_F(Ac20PowerUp, ConfigurationModeInRemoteIsKeptAcrossPowerOff_Note5) {
    Simulated before("ac20");
    enter_configuration(before);
    power_off(before);
    EXPECT_NE(file_text().find("\"condition\""), std::string::npos) << file_text();

    Simulated after("ac20");
    power_on(after);
    EXPECT_EQ(after.word(135), 6) << "configuration mode kept";
    EXPECT_TRUE(after.bit(218)) << "remote kept";
    EXPECT_EQ(after.write(2000, 1), echo_word(2000, 1)) << "word 2000 writable: configuration mode, remote";
}

// Note 5, "in the other cases": security code mode in local (bit 218 cleared after entering it)
// comes back in security code mode, in local.
TEST_F(Ac20PowerUp, SecurityCodeModeInLocalIsKeptAcrossPowerOff_Note5) {
    Simulated before("ac20");
    enter_security(before);
    ASSERT_EQ(set_bit(before, 218, false), echo_bit(218, false));
    power_off(before);

    Simulated after("ac20");
    power_on(after);
    EXPECT_EQ(after.word(135), 7) << "security code mode kept";
    EXPECT_FALSE(after.bit(218)) << "local kept";
    EXPECT_EQ(after.write(4001, 5), "86 0A") << "local: nothing but bit 218 can be modified";
}

// Note 5: more than 3 s of a quiet line before the power-off: the device was back in local
// ("every slave will automatically return to local mode"), and powers up so, in configuration mode.
TEST_F(Ac20PowerUp, QuietLineBeforePowerOffMeansLocalAtPowerUp_Note5) {
    Simulated before("ac20");
    enter_configuration(before);
    before.wait(3.5);
    power_off(before);

    Simulated after("ac20");
    power_on(after);
    EXPECT_EQ(after.word(135), 6);
    EXPECT_FALSE(after.bit(218));
}

// Note 5: "the slave will be in local mode if it was in control mode at power off".
TEST_F(Ac20PowerUp, ControlModeInRemoteComesBackLocal_Note5) {
    Simulated before("ac20");
    go_remote(before);
    power_off(before);

    Simulated after("ac20");
    power_on(after);
    EXPECT_EQ(after.word(135), 0) << "control mode";
    EXPECT_FALSE(after.bit(218)) << "local after power-up from control mode";
}

// A state file written before the condition was kept (no "condition") loads as before: the
// saved words come back and the device powers up in control mode, local.
TEST_F(Ac20PowerUp, StateFileWithoutConditionLoadsAsBefore_Note5) {
    std::ofstream(path) << R"({"format": "loopwire-simulator-state", "version": 1,
                               "units": {"3": {"profile": "ac20", "saved": {"main_set_point": 95}}}})";
    Simulated after("ac20");
    power_on(after);
    EXPECT_EQ(after.word(138), 95);
    EXPECT_EQ(after.word(135), 0);
    EXPECT_FALSE(after.bit(218));
}

// Entering a mode changes what a power-off keeps: the state file is due to be saved again.
TEST_F(Ac20PowerUp, EnteringAModeMakesTheStateFileDue_Note5) {
    Simulated dev("ac20");
    auto state = SimulatorStateFile::open(path, {{3, std::shared_ptr<SimulatedDevice>(&dev.device(), [](SimulatedDevice*) {})}});
    ASSERT_TRUE(state) << state.error().message;
    ASSERT_FALSE(state->has_unsaved_changes());
    go_remote(dev);
    EXPECT_TRUE(state->has_unsaved_changes()) << "bit 218 is part of the condition";
    ASSERT_TRUE(state->save_if_changed());
    ASSERT_EQ(dev.write(347, 0), echo_word(347, 0));
    EXPECT_TRUE(state->has_unsaved_changes()) << "configuration mode is part of the condition";
}

// --- Note 5: line activity on a shared line ---------------------------------------------------

// Two AC20s (units 1 and 2) on one RTU line in virtual time; the slave session serves both.
class Ac20SharedLine : public ::testing::Test {
protected:
    std::shared_ptr<SimulatedDevice> make_unit(std::uint8_t unit) {
        auto environment = SimulationEnvironment{}.on_line(unit, link);
        environment.now = [clock = clock] { return clock->now(); };
        return models::make_simulated_device(builtin("ac20"), std::move(environment));
    }
    // Serves the frames given (each at its instant) until the line is done; returns the replies.
    std::vector<std::string> serve() {
        session::SlaveOptions options;
        options.clock = clock;
        session::Slave slave(link, session::UnitMap{{1, unit1}, {2, unit2}}, options);
        EXPECT_TRUE(slave.serve_stream(line, stop.get_token()).ok());
        std::vector<std::string> replies;
        for (const auto& write : line.writes()) replies.push_back(to_hex(write.bytes));
        return replies;
    }
    void arrive(double seconds, Bytes frame) {
        line.arrive(start + std::chrono::duration_cast<Instant::duration>(std::chrono::duration<double>(seconds)), std::move(frame));
    }
    static Bytes frame(std::uint8_t unit, const char* pdu) { return codec::rtu_encode(unit, hex(pdu)); }
    static std::string reply(std::uint8_t unit, const char* pdu) { return to_hex(codec::rtu_encode(unit, hex(pdu))); }

    const transport::LinkUrl link = *transport::parse_link_url("rtu:virtual?baud=9600&parity=none");
    std::shared_ptr<VirtualClock> clock = std::make_shared<VirtualClock>();
    const Instant start = clock->now();
    std::stop_source stop;
    loopwire::testing::VirtualLine line{clock, stop};
    std::shared_ptr<SimulatedDevice> unit1 = make_unit(1);
    std::shared_ptr<SimulatedDevice> unit2 = make_unit(2);
};

// Note 5: "For a slave to remain in remote status, it is sufficient to detect line activity. If
// there is no line activity for more than 3 sec. every slave will automatically return to local
// mode." The master puts unit 1 in remote, then talks only to unit 2 for 10 s: unit 1 hears that
// traffic and stays remote; after 3.5 s of a quiet line it is local.
TEST_F(Ac20SharedLine, FramesForAnotherSlaveKeepARemoteSlaveRemote_Note5) {
    arrive(0.0, frame(1, "05 00 DA FF 00"));                                  // unit 1: bit 218 on
    for (double at = 0.5; at <= 10.0; at += 0.5) arrive(at + 0.5, frame(2, "03 00 78 00 01"));  // unit 2: word 120
    arrive(11.5, frame(1, "01 00 DA 00 01"));                                 // unit 1: bit 218? (1 s after the last)
    arrive(15.0, frame(1, "01 00 DA 00 01"));                                 // 3.5 s of quiet line
    const auto replies = serve();
    ASSERT_EQ(replies.size(), 23u);
    EXPECT_EQ(replies.front(), reply(1, "05 00 DA FF 00"));
    EXPECT_EQ(replies[21], reply(1, "01 01 01")) << "unit 1 still remote after 10 s of frames for unit 2";
    EXPECT_EQ(replies[22], reply(1, "01 01 00")) << "unit 1 local after more than 3 s of a quiet line";
}

// Bytes that fail their check are on the line too (choice, profiles/NOTES.md): unit 1 stays
// remote while only corrupted frames go past.
TEST_F(Ac20SharedLine, FramesWithABadCheckAreLineActivity_Note5) {
    arrive(0.0, frame(1, "05 00 DA FF 00"));
    Bytes corrupted = frame(2, "03 00 78 00 01");
    corrupted.back() ^= 0xFF;
    for (double at = 2.0; at <= 8.0; at += 2.0) arrive(at, corrupted);
    arrive(10.0, frame(1, "01 00 DA 00 01"));
    const auto replies = serve();
    ASSERT_EQ(replies.size(), 2u);
    EXPECT_EQ(replies[1], reply(1, "01 01 01")) << "still remote: a corrupted frame every 2 s";
}

}  // namespace
}  // namespace loopwire::device
