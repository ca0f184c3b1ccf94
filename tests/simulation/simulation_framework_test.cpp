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
    EXPECT_EQ(device.steps, 1000);
    EXPECT_NEAR(device.longest, SimulatedDevice::max_process_step, 1e-12);
    clock.advance(1e6);  // a long pause: still a bounded number of steps
    device.advance();
    EXPECT_NEAR(device.total, 100.0 + 5e7, 1.0);
    EXPECT_LE(device.steps, 1000 + 20000);
}

// Time shorter than a step waits for the next request instead of becoming a short step: the
// process walks a fixed grid of process time.
TEST(SimulationFramework, ProcessTimeShorterThanAStepIsCarriedToTheNextRequest) {
    ManualClock clock;
    SimulationEnvironment environment;
    environment.now = clock.function();
    StepCounter device(builtin("tc10"), environment);
    for (int poll = 0; poll < 7; ++poll) {
        clock.advance(0.03);
        device.advance();
    }
    EXPECT_EQ(device.steps, 2) << "0.21 s of process time: two steps of 0.1 s, 0.01 s carried";
    EXPECT_NEAR(device.total, 0.2, 1e-12);
    clock.advance(0.09);
    device.advance();
    EXPECT_EQ(device.steps, 3);
}

// What a client reads at these process times, polling every `poll_every` seconds of real time
// in between (0: not at all).
std::vector<Words> trajectory(const std::string& id, std::uint64_t seed, double poll_every,
                              const std::vector<std::string>& names) {
    SimulationEnvironment environment;
    environment.seed = seed;
    environment.speed = 7;
    Simulated device(id, Model::behaviour, environment);
    const auto& profile = device.device().profile();
    // A set point away from the start, so the process moves (the AC20 takes it in remote).
    if (id == "ac20") {
        (void)device.send(codec::write_single_coil(218, true));
        (void)device.write(profile.find("main_set_point")->address, 110);
    }
    if (id == "rampsoak") (void)device.write(profile.find("set_value")->address, 1500);  // 150.0
    if (id == "tc10") (void)device.write(profile.find("set_point")->address, 200);
    std::vector<Words> samples;
    double now = 0;
    for (int second = 1; second <= 40; ++second) {
        // Sampled off the grid (7 * 0.013 = 0.091 s past a step), where no rounding of the
        // clock can move a sample across a step.
        const double sample_at = second + 0.013;
        while (poll_every > 0 && now + poll_every < sample_at) {
            device.wait(poll_every);
            now += poll_every;
            (void)device.word(profile.find(names.front())->address);
        }
        device.wait(sample_at - now);
        now = sample_at;
        Words sample;
        for (const auto& name : names) sample.push_back(device.word(profile.find(name)->address));
        samples.push_back(sample);
    }
    return samples;
}

// --seed makes runs reproducible: the same seed gives the same readings at the same
// process times, whether a client polled every 50 ms, every 1.3 s or never in between; noise
// follows the seed.
TEST(SimulationFramework, SameSeedSameTrajectoryHoweverOftenClientsPoll) {
    const std::vector<std::pair<std::string, std::vector<std::string>>> devices{
        {"ac20", {"probe_millivolts", "carbon_potential", "dew_point"}},
        {"rampsoak", {"process_value", "output_percentage"}},
        {"tc10", {"measured_value", "output_power"}}};
    for (const auto& [id, names] : devices) {
        const auto quiet = trajectory(id, 42, 0, names);
        EXPECT_EQ(trajectory(id, 42, 0.05, names), quiet) << id;
        EXPECT_EQ(trajectory(id, 42, 1.3, names), quiet) << id;
        EXPECT_NE(quiet.front(), quiet.back()) << id << ": the process should move in 280 process seconds";
    }
    for (const std::string id : {"ac20", "rampsoak"}) {  // the TC10 model draws no noise
        const auto& names = std::find_if(devices.begin(), devices.end(), [&](const auto& d) { return d.first == id; })->second;
        EXPECT_NE(trajectory(id, 42, 0, names), trajectory(id, 43, 0, names)) << id << ": noise ignores the seed";
    }
}

}  // namespace
}  // namespace loopwire::device
