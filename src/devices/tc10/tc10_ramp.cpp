#include "devices/tc10/tc10_ramp.hpp"

#include <algorithm>
#include <cmath>

namespace loopwire::device::models::tc10 {
namespace {

// Closer than this (engineering units) the ramp has arrived: below a thousandth of the finest
// display count (dP = 3).
constexpr double arrived = 1e-6;

}  // namespace

// #86 "Скорость нарастания для ПОЛОЖИТЕЛЬНОГО изменения уставки (повышение) … ед. измерения в
// минуту" (rise rate for a positive set-point change, units per minute) and #87 the same for a
// negative change (понижение, lowering).
void SetPointRamp::step(double seconds, double target, double start, const RampRates& rates) {
    if (!working_) working_ = start;
    const bool rising = target > *working_;
    const std::optional<double> rate = rising ? rates.up : rates.down;
    if (!rate) {
        working_ = target;
        return;
    }
    const double move = *rate * seconds / 60.0;
    working_ = rising ? std::min(target, *working_ + move) : std::max(target, *working_ - move);
}

bool SetPointRamp::running(double target) const { return working_ && std::abs(*working_ - target) > arrived; }

}  // namespace loopwire::device::models::tc10
