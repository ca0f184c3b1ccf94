#include "devices/rampsoak/rampsoak_program.hpp"

#include <algorithm>
#include <cmath>

namespace loopwire::device::models {

void RampSoakProgram::start(double start_point) {
    running_ = true;
    ended_ = false;
    segment_ = 0;
    elapsed_ = 0;
    segment_start_ = start_point;
}

void RampSoakProgram::stop() {
    running_ = false;
    ended_ = false;
}

// The end holds the set point the last segment reached (segment_start_ after the hand-over).
void RampSoakProgram::finish() {
    running_ = false;
    ended_ = true;
}

void RampSoakProgram::step(double seconds, const ProgramPattern& pattern) {
    if (!running_) return;
    elapsed_ += seconds;
    // A long step may cross several segments; a segment with no run time ends the pattern.
    while (running_) {
        const ProgramSegment& segment = pattern[segment_];
        if (segment.run_time <= 0) {
            finish();
            break;
        }
        if (elapsed_ < segment.run_time) break;
        elapsed_ -= segment.run_time;
        segment_start_ = segment.set_point;
        if (++segment_ == pattern.size()) {
            segment_ = pattern.size() - 1;
            finish();
        }
    }
}

std::optional<double> RampSoakProgram::working_set_point(const ProgramPattern& pattern) const {
    if (ended_) return segment_start_;
    if (!running_) return std::nullopt;
    const ProgramSegment& segment = pattern[segment_];
    if (segment.run_time <= 0) return segment_start_;
    const double fraction = std::min(1.0, elapsed_ / segment.run_time);
    return segment_start_ + (segment.set_point - segment_start_) * fraction;
}

std::uint16_t RampSoakProgram::remaining_minutes(const ProgramPattern& pattern) const {
    if (!running_) return 0;
    const double left = pattern[segment_].run_time - elapsed_;
    return left <= 0 ? 0 : static_cast<std::uint16_t>(std::ceil(left / 60.0));
}

std::optional<double> RampSoakProgram::output_limit(const ProgramPattern& pattern) const {
    if (!running_) return std::nullopt;
    return pattern[segment_].output_limit;
}

}  // namespace loopwire::device::models
