#pragma once
// Shared by the TC10 model tests: the addresses they use and a write that must be accepted.
// The oven starts at 25 °C with the heater off; the factory settings are the simulator's
// (Pb 20, ti 120 s, td 10 s, output 1 heating, output 2 = alarm 1 relay, dP = 0), since the
// manual lists none.
#include <gtest/gtest.h>

#include <cstdint>

#include "codec/pdu.hpp"
#include "simulation/simulator_harness.hpp"

namespace loopwire::device::tc10_testing {

using testing::Simulated;

// §5.1 / §5.2 / §5.3 addresses (Dec column).
inline constexpr std::uint16_t measured = 1, decimals = 2, working_sp = 3, output_power = 4;
inline constexpr std::uint16_t alarm_status = 10, output_status = 11, instrument_status = 12;
inline constexpr std::uint16_t alarm_reset = 13, alarm_acknowledge = 14, control_state = 15;
inline constexpr std::uint16_t remote_sp = 16, error_output = 18, load_defaults = 19;
inline constexpr std::uint16_t heating_power = 515, alarm_1_state = 517, alarm_2_state = 518, controller_state = 527;
inline constexpr std::uint16_t output_1_remote = 548, manual_output = 592;
inline constexpr std::uint16_t decimal_point = 641, sensor_error_mode = 646, output_1_function = 652;
inline constexpr std::uint16_t al1_type = 666, al1_function = 667, al1_low = 668, al1_high = 669, al1 = 670;
inline constexpr std::uint16_t al1_hysteresis = 671, al1_delay = 672, al1_enable = 673, al2_type = 674;
inline constexpr std::uint16_t proportional_band = 700, integral_time = 701, derivative_time = 702;
inline constexpr std::uint16_t set_point = 717, remote_sp_type = 722, local_remote = 723;
inline constexpr std::uint16_t modes_enable = 767, operating_mode = 768, device_address = 769, baud_rate = 770;

inline constexpr std::uint16_t manual = 1, standby = 2;

// An in-range write must get the standard reply (§4.4 B.1).
inline void set(Simulated& tc10, std::uint16_t address, int value) {
    const auto request = codec::write_single_register(address, testing::raw(value));
    EXPECT_EQ(tc10.send(request), testing::echo_of(request)) << "write " << value << " to " << address;
}

inline bool bit(std::uint16_t word, unsigned position) { return ((unsigned{word} >> position) & 1U) != 0; }

inline SimulationEnvironment at_speed(double speed) {
    SimulationEnvironment environment;
    environment.speed = speed;
    return environment;
}

}  // namespace loopwire::device::tc10_testing
