// Set point limits of the ramp/soak controller: LSPL (§7, 004CH, "Lower Set Point Limit") and
// USPL (004DH, "Upper Set Point Limit"). The map prints no range for SV or the segment set
// points; the limits' names say what bounds them. A write outside them is refused with §4.6
// abnormal code 03, "Illegal data value (Data value is out of setting range)", and nothing is
// stored. Choices (the manual states no more):
// - The fixed SV (0000H) and every segment set point SV_n (pattern 1 and 2) are bounded: each
//   becomes the working set point when its turn comes.
// - LSPL may not rise above USPL, nor USPL fall below LSPL (the pair would refuse every SV).
// - Moving a limit does not change a set point already stored outside the new limits.
// - Limits and set points are compared as the signed words they are: both carry DP (004BH).
#include <algorithm>

#include "devices/rampsoak/rampsoak_simulator.hpp"

namespace loopwire::device::models {
namespace {

constexpr std::uint8_t out_of_setting_range = 0x03;  // §4.6 abnormal code 03

std::int16_t signed_raw(std::uint16_t raw) { return static_cast<std::int16_t>(raw); }

}  // namespace

bool RampSoakSimulator::is_set_point(const Parameter& parameter) const {
    if (&parameter == set_value_->parameter) return true;
    return std::any_of(patterns_.begin(), patterns_.end(), [&](const PatternCells& cells) {
        return std::any_of(cells.begin(), cells.end(),
                           [&](const SegmentCells& segment) { return segment.set_point->parameter == &parameter; });
    });
}

std::optional<std::uint8_t> RampSoakSimulator::accept_write(const Parameter& parameter, std::uint16_t raw,
                                                            const RawValues&) {
    const std::int16_t value = signed_raw(raw);
    const std::int16_t lower = signed_raw(lower_set_point_limit_->raw);
    const std::int16_t upper = signed_raw(upper_set_point_limit_->raw);
    if (is_set_point(parameter) && (value < lower || value > upper)) return out_of_setting_range;
    if (&parameter == lower_set_point_limit_->parameter && value > upper) return out_of_setting_range;
    if (&parameter == upper_set_point_limit_->parameter && value < lower) return out_of_setting_range;
    return std::nullopt;
}

}  // namespace loopwire::device::models
