#pragma once
// What a simulated device takes from the world around it: clocks and randomness are injected
// (docs/DESIGN.md: "time and randomness are injected so tests are deterministic").
#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <optional>
#include <utility>

#include "transport/link_url.hpp"

namespace loopwire::device {

using SimulationClock = std::chrono::steady_clock;

struct SimulationEnvironment {
    // Protocol time: what the device's own timeouts run on (AC20 3 s remote timeout). Always
    // real time for clients; tests inject a clock they move by hand.
    std::function<SimulationClock::time_point()> now = [] { return SimulationClock::now(); };
    // Process seconds per protocol second (--speed): plants and program timers run this much
    // faster; protocol timing never does.
    double speed = 1.0;
    // Seeds measurement noise and anything else random (--seed), so runs repeat exactly.
    std::uint64_t seed = 1;
    // The framing the device is served with ("rtu", "ascii", "linking", "tcp"): the ramp/soak
    // controller's Linking M request modifies RAM only, its W request RAM and EEPROM.
    std::string framing = "rtu";
    // The unit id the device answers at, and the serial settings of the line it is served on
    // (none on TCP): a device reports them in its own words (AC20 526-529, TC10 Add/bAud,
    // ramp/soak PSL/BITS/IDNO/BAUD), as a real one set up for that line would.
    std::uint8_t unit = 1;
    std::optional<transport::SerialSettings> serial;

    // The environment of the device at `unit` on a line served with `line_framing`: each unit
    // its own noise, as one seed on two units would make them move in lockstep.
    SimulationEnvironment for_unit(std::uint8_t served_unit, std::string line_framing) const {
        SimulationEnvironment environment = *this;
        environment.seed = seed * 1000003ULL + served_unit;
        environment.framing = std::move(line_framing);
        environment.unit = served_unit;
        return environment;
    }

    // The same, served as `unit` on `link`: its framing and, on a serial line, its settings.
    SimulationEnvironment on_line(std::uint8_t served_unit, const transport::LinkUrl& link) const {
        SimulationEnvironment environment = for_unit(served_unit, transport::framing_name(link.framing));
        if (link.is_serial()) environment.serial = link.serial;
        return environment;
    }
};

}  // namespace loopwire::device
