#pragma once
// The ramp/soak program of the ramp/soak controller: a pattern of up to 8 segments, each with
// a set point SV_n, a run time TM_n and an output limit OUTn (rampsoak manual §7 Register Map,
// rows 0009H-0038H: pattern 1 at 0009H, pattern 2 at 0021H, three words per segment).
//
// The manual lists the registers but not how a program runs; what this model does (each choice
// is tested in tests/devices/rampsoak/rampsoak_simulator_test.cpp):
// - Segment n ramps the working set point linearly from where segment n-1 ended (segment 1:
//   from the PV at the start) to SV_n over TM_n; a soak is a segment whose SV_n equals the
//   previous one. Ramping from the PV avoids a step at the start, as program controllers do.
// - TM_n counts minutes: the manual prints no unit, and minutes are what a furnace program of
//   8 segments needs (TM is a raw word; seconds would cap a segment at 18 hours only with
//   uint16, minutes reach 45 days).
// - A segment with TM_n = 0 ends the pattern: the segments after it are not run, so a pattern
//   may have fewer than 8 segments.
// - At the end the program stops and the controller holds the last segment's set point.
#include <array>
#include <cstdint>
#include <optional>

namespace loopwire::device::models {

struct ProgramSegment {
    double set_point = 0;        // engineering units (°C with DP applied)
    double run_time = 0;         // seconds
    double output_limit = 100;   // %
};

inline constexpr std::size_t segments_per_pattern = 8;
using ProgramPattern = std::array<ProgramSegment, segments_per_pattern>;

class RampSoakProgram {
public:
    // Starts the pattern from segment 1 with the working set point at `start_point` (the PV).
    void start(double start_point);
    // Stops the program; the controller goes back to the fixed set point.
    void stop();

    // Advances by `seconds` of process time through `pattern`, read afresh each step so a
    // segment edited while it runs takes effect at once.
    void step(double seconds, const ProgramPattern& pattern);

    bool running() const { return running_; }
    // Whether the program has run to its end and holds the last set point.
    bool ended() const { return ended_; }
    // The working set point while running or after the end; nullopt when no program is active.
    std::optional<double> working_set_point(const ProgramPattern& pattern) const;
    // 1-based segment number while running, 0 otherwise (SEG, 0007H).
    std::uint16_t segment_number() const { return running_ ? static_cast<std::uint16_t>(segment_ + 1) : 0; }
    // Whole minutes left in the running segment, rounded up; 0 when not running (TIMR, 0008H).
    std::uint16_t remaining_minutes(const ProgramPattern& pattern) const;
    // The running segment's output limit, or nullopt when not running.
    std::optional<double> output_limit(const ProgramPattern& pattern) const;

private:
    void finish();

    bool running_ = false;
    bool ended_ = false;
    std::size_t segment_ = 0;
    double elapsed_ = 0;        // seconds into the running segment
    double segment_start_ = 0;  // working set point when the running segment began
};

}  // namespace loopwire::device::models
