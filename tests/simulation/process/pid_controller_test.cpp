// The PID controller closes the loop on the thermal plant: PV reaches SP without offset.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "simulation/process/pid_controller.hpp"
#include "simulation/process/thermal_plant.hpp"

namespace loopwire::device::process {
namespace {

TEST(PidController, ProportionalOutputIsHundredPercentPerBand) {
    PidController pid({10.0, 0.0, 0.0, 1000.0, 0.0, 100.0, 0.5});  // band = 100 units
    EXPECT_NEAR(pid.step(1.0, 500.0, 450.0), 50.0, 1e-9);
    EXPECT_NEAR(pid.step(1.0, 500.0, 300.0), 100.0, 1e-9);
    EXPECT_NEAR(pid.step(1.0, 500.0, 600.0), 0.0, 1e-9);
}

TEST(PidController, ClosedLoopSettlesOnTheSetPoint) {
    ThermalPlant plant({25.0, 1000.0, 300.0, 10.0});
    PidController pid({20.0, 200.0, 30.0, 1000.0, 0.0, 100.0, 0.5});
    for (int i = 0; i < 60000; ++i) plant.step(0.1, pid.step(0.1, 600.0, plant.temperature()) / 100.0);
    EXPECT_NEAR(plant.temperature(), 600.0, 1.0);
    EXPECT_NEAR(pid.output(), (600.0 - 25.0) / 1000.0 * 100.0, 1.0);
}

TEST(PidController, OnOffControlSwitchesAroundTheSetPoint) {
    PidController pid({0.0, 0.0, 0.0, 1000.0, 0.0, 100.0, 2.0});
    EXPECT_EQ(pid.step(1.0, 100.0, 90.0), 100.0);
    EXPECT_EQ(pid.step(1.0, 100.0, 99.0), 100.0);  // inside the hysteresis: unchanged
    EXPECT_EQ(pid.step(1.0, 100.0, 100.0), 0.0);
    EXPECT_EQ(pid.step(1.0, 100.0, 99.0), 0.0);
}

TEST(PidController, TrackingMakesTheSwitchToAutomaticBumpless) {
    PidController pid({5.0, 200.0, 0.0, 1000.0, 0.0, 100.0, 0.5});
    pid.track(42.0, 500.0, 490.0);
    EXPECT_NEAR(pid.step(0.001, 500.0, 490.0), 42.0, 0.1);
}

// A controller sees its input in display counts: each one-count step of a rising PV must not
// read as a spike that throws the output to 0 % while the PV is far below SP (the derivative
// filter, pid_controller.hpp). The TC10 simulator's oven, Pb 20 units, ti 120 s and a long
// derivative time, td 30 s; the PID stepped every 0.1 s.
TEST(PidController, MeasurementInWholeCountsDoesNotKickTheOutputWhileFarBelowSetPoint) {
    ThermalPlant plant({25.0, 400.0, 300.0, 10.0});
    PidController pid({20.0, 120.0, 30.0, 100.0, 0.0, 100.0, 0.5});
    double lowest = 100.0;
    while (plant.temperature() < 150.0) {
        const double output = pid.step(0.1, 300.0, std::round(plant.temperature()));
        lowest = std::min(lowest, output);
        plant.step(0.1, output / 100.0);
    }
    EXPECT_EQ(lowest, 100.0);
}

}  // namespace
}  // namespace loopwire::device::process
