#pragma once
// The TC10's set-point ramp (tc10-modbus-im05c01e81-03.ru.txt §5.3.8 #86 SP.u, #87 SP.d; status
// §5.1 12A bit 9): the working set point (§5.1 3A) moves towards the final one at a limited rate.
#include <optional>

namespace loopwire::device::models::tc10 {

// Rates in engineering units per minute; nullopt = inF, no limit (the set point steps).
struct RampRates {
    std::optional<double> up;
    std::optional<double> down;
};

class SetPointRamp {
public:
    // Advances by `seconds` towards `target`. A ramp that has no working set point yet (power-on,
    // restart()) starts from `start` — the measured value, or the target when there is none.
    void step(double seconds, double target, double start, const RampRates& rates);
    // The next step starts the ramp again from its `start`.
    void restart() { working_.reset(); }
    // The working set point, or nullopt before the first step.
    std::optional<double> working() const { return working_; }
    // True while the working set point has not reached `target`.
    bool running(double target) const;

private:
    std::optional<double> working_;
};

}  // namespace loopwire::device::models::tc10
