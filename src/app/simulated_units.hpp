#pragma once
// The units `loopwire simulate` serves: plain register banks (--unit N) and simulated devices
// from their profiles (--device DEVICE@UNIT).
#include <string>
#include <vector>

#include "common/result.hpp"
#include "session/slave.hpp"
#include "transport/link_url.hpp"

namespace loopwire::app {

struct SimulatedUnits {
    session::UnitMap units;
    std::vector<std::string> descriptions;  // one line per unit: "3: tc10 (Yokogawa TC10 ...)"
    std::vector<std::string> warnings;      // link settings the real device cannot have
};

// A unit named twice, or an unknown device, is a usage error. With neither list given, unit 1
// is a plain bank.
Result<SimulatedUnits> build_simulated_units(const std::vector<int>& bank_units, const std::vector<std::string>& devices,
                                             const transport::LinkUrl& link);

}  // namespace loopwire::app
