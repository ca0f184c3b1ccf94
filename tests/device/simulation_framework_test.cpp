// What every simulated device shares, through the wire: numbering alternatives chosen by a
// word (AC20 J-BUS), saved vs RAM-only contents (--state), time injected (--speed) and faults.
#include <gtest/gtest.h>

#include "simulator_harness.hpp"

namespace loopwire::device {
namespace {

using namespace testing;

// AC20 profile: word 526 selects the protocol (1 = Modbus, 2 = J-BUS: listed address + 1).
// The switch takes effect with the next request (AC20 "Communication parameters": serial
// settings apply after the reply). Through the profile-only simulator: the rule is data.
TEST(SimulationFramework, Ac20Word526SelectsJbusNumberingFromTheNextRequest_ModbusJbusSection) {
    Simulated ac20("ac20", Model::profile_only);
    const std::uint16_t identification = ac20.word(120);
    ASSERT_EQ(identification, 50);
    EXPECT_EQ(ac20.write(526, 2), echo_of(codec::write_single_register(526, 2)));
    EXPECT_EQ(ac20.word(121), identification) << "word 120 now answers at wire address 121";
    EXPECT_EQ(ac20.write(527, 1), echo_of(codec::write_single_register(527, 1)));
    EXPECT_EQ(ac20.word(120), identification) << "back to Modbus numbering";
}

TEST(SimulationFramework, SavedValuesHoldWrittenParametersButNotRamOnlyOnes) {
    Simulated tc10("tc10", Model::profile_only);
    ASSERT_EQ(tc10.write(717, 150), echo_of(codec::write_single_register(717, 150)));  // SP, EEPROM
    const auto saved = tc10.device().saved_values();
    ASSERT_TRUE(saved.contains("set_point"));
    EXPECT_EQ(saved.at("set_point"), 150);
    for (const Parameter& parameter : tc10.device().profile().parameters) {
        if (parameter.ram_only) {
            EXPECT_FALSE(saved.contains(parameter.name)) << parameter.name;
        }
    }
    Simulated restarted("tc10", Model::profile_only);
    EXPECT_TRUE(restarted.device().load_saved(saved).empty());
    EXPECT_EQ(restarted.word(717), 150);
}

TEST(SimulationFramework, SavedGenerationMovesOnlyWhenASavedValueChanges) {
    Simulated tc10("tc10", Model::profile_only);
    const auto before = tc10.device().saved_generation();
    tc10.read(640, 4);
    EXPECT_EQ(tc10.device().saved_generation(), before);
    tc10.write(717, 151);
    EXPECT_GT(tc10.device().saved_generation(), before);
}

TEST(SimulationFramework, UnknownSavedNamesAreReportedNotLoaded) {
    Simulated tc10("tc10", Model::profile_only);
    EXPECT_EQ(tc10.device().load_saved({{"no_such_parameter", 3}}), std::vector<std::string>{"no_such_parameter"});
}

TEST(SimulationFramework, UnknownFaultIsAUsageErrorNamingTheKnownOnes) {
    Simulated tc10("tc10", Model::profile_only);
    auto result = tc10.device().inject_fault("melted");
    ASSERT_FALSE(result);
    EXPECT_EQ(result.error().kind, ErrorKind::usage);
    EXPECT_NE(result.error().message.find("melted"), std::string::npos) << result.error().message;
}

// A device whose process counts the time it was given, to check the clock arithmetic.
class StepCounter : public SimulatedDevice {
public:
    using SimulatedDevice::SimulatedDevice;
    double total = 0;
    int steps = 0;
    double longest = 0;

protected:
    void step_process(double seconds) override {
        total += seconds;
        ++steps;
        longest = std::max(longest, seconds);
    }
};

TEST(SimulationFramework, ProcessRunsAtSpeedTimesTheClockInBoundedSteps) {
    ManualClock clock;
    SimulationEnvironment environment;
    environment.now = clock.function();
    environment.speed = 50;
    StepCounter device(builtin("tc10"), environment);
    clock.advance(2.0);
    device.advance();
    EXPECT_NEAR(device.total, 100.0, 1e-6);
    EXPECT_LE(device.longest, SimulatedDevice::max_process_step + 1e-9);
    clock.advance(1e6);  // a long pause: still a bounded number of steps
    device.advance();
    EXPECT_NEAR(device.total, 100.0 + 5e7, 1.0);
    EXPECT_LE(device.steps, 1000 + 20000);
}

}  // namespace
}  // namespace loopwire::device
