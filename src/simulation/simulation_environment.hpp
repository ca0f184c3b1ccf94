#pragma once
// What a simulated device takes from the world around it: clocks and randomness are injected
// (docs/DESIGN.md: "time and randomness are injected so tests are deterministic").
#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace loopwire::device {

using SimulationClock = std::chrono::steady_clock;

struct SimulationEnvironment {
    // Protocol time: what the device's own timeouts run on (AC20 3 s remote timeout). Always
    // real time for clients; tests inject a clock they move by hand.
    std::function<SimulationClock::time_point()> now = [] { return SimulationClock::now(); };
    // Process seconds per protocol second (--speed): plants and program timers run this much
    // faster; protocol timing never does (issue 4, "--speed scales the process").
    double speed = 1.0;
    // Seeds measurement noise and anything else random (--seed), so runs repeat exactly.
    std::uint64_t seed = 1;
    // The framing the device is served with ("rtu", "ascii", "linking", "tcp"): the ramp/soak
    // controller's Linking M request modifies RAM only, its W request RAM and EEPROM.
    std::string framing = "rtu";
};

}  // namespace loopwire::device
