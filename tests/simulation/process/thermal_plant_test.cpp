// The plant model's equations (thermal_plant.hpp), checked against their closed forms.
#include <gtest/gtest.h>

#include <cmath>

#include "simulation/process/thermal_plant.hpp"

namespace loopwire::device::process {
namespace {

TEST(ThermalPlant, SettlesAtAmbientPlusGainTimesOutput) {
    ThermalPlant plant({20.0, 800.0, 100.0, 5.0});
    for (int i = 0; i < 20000; ++i) plant.step(0.1, 0.5);
    EXPECT_NEAR(plant.temperature(), 20.0 + 400.0, 0.01);
}

TEST(ThermalPlant, FollowsTheFirstOrderCurveAfterTheDeadTime) {
    ThermalPlant plant({0.0, 100.0, 50.0, 10.0});
    for (int i = 0; i < 100; ++i) plant.step(0.1, 1.0);  // 10 s: the heat has not arrived yet
    EXPECT_NEAR(plant.temperature(), 0.0, 1e-9);
    for (int i = 0; i < 500; ++i) plant.step(0.1, 1.0);  // 50 s more = one time constant
    EXPECT_NEAR(plant.temperature(), 100.0 * (1 - std::exp(-1.0)), 0.5);
}

TEST(ThermalPlant, CoolsTowardsAmbientWithoutOutput) {
    ThermalPlant plant({25.0, 1000.0, 200.0, 0.0});
    plant.set_temperature(500.0);
    for (int i = 0; i < 2000; ++i) plant.step(0.1, 0.0);  // one time constant
    EXPECT_NEAR(plant.temperature(), 25.0 + 475.0 * std::exp(-1.0), 0.5);
}

TEST(ThermalPlant, OutputIsClampedToZeroToOne) {
    ThermalPlant plant({0.0, 100.0, 10.0, 0.0});
    for (int i = 0; i < 2000; ++i) plant.step(0.1, 7.0);
    EXPECT_NEAR(plant.temperature(), 100.0, 0.01);
}

}  // namespace
}  // namespace loopwire::device::process
