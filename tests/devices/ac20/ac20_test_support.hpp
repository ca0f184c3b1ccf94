#pragma once
// Shared by the AC20 model tests: the steps a master takes to reach a mode (ENG. 824E rev. 1,
// Notes 5-8) and a clock that keeps the device in remote.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "codec/pdu.hpp"
#include "simulation/simulator_harness.hpp"

namespace loopwire::device::ac20_testing {

using testing::echo_of;
using testing::Simulated;

inline SimulationEnvironment at_speed(double speed) {
    SimulationEnvironment environment;
    environment.speed = speed;
    return environment;
}

inline std::string set_bit(Simulated& dev, std::uint16_t bit, bool on = true) {
    return dev.send(codec::write_single_coil(bit, on));
}
inline std::string echo_bit(std::uint16_t bit, bool on = true) { return echo_of(codec::write_single_coil(bit, on)); }
inline std::string echo_word(std::uint16_t address, std::uint16_t value) {
    return echo_of(codec::write_single_register(address, value));
}

inline void go_remote(Simulated& dev) { ASSERT_EQ(set_bit(dev, 218), echo_bit(218)); }

// Moves the clock in steps short enough to keep the device in remote (Note 5), reading a word
// at each step as a polling master would.
inline void poll(Simulated& dev, double real_seconds, double step = 1.0) {
    for (double done = 0; done < real_seconds - 1e-9; done += step) {
        dev.wait(std::min(step, real_seconds - done));
        (void)dev.word(120);
    }
}

// Remote, then configuration mode with the factory combination 0 (Note 7).
inline void enter_configuration(Simulated& dev) {
    go_remote(dev);
    ASSERT_EQ(dev.write(347, 0), echo_word(347, 0));
    ASSERT_EQ(dev.word(135), 6);
}
inline void enter_security(Simulated& dev) {
    go_remote(dev);
    ASSERT_EQ(dev.write(348, 0), echo_word(348, 0));
    ASSERT_EQ(dev.word(135), 7);
}
inline void leave_to_control(Simulated& dev) { ASSERT_EQ(dev.write(3051, 1), echo_word(3051, 1)); }

// Past the 5 minutes after power-on that a procedure waits for (error 52), at --speed 100.
inline void past_start_up(Simulated& dev) { poll(dev, 3.1); }

}  // namespace loopwire::device::ac20_testing
