#include "devices/rampsoak/rampsoak_alarms.hpp"

#include <cmath>

namespace loopwire::device::models {

bool alarm_on(std::uint16_t mode, double set, std::int16_t set_raw, const AlarmInputs& inputs) {
    const double pv = inputs.process_value;
    const double sv = inputs.set_point;
    const double width = std::fabs(set);
    switch (mode) {
        case 1: return pv >= sv + set;
        case 2: return pv <= sv + set;
        case 3: return pv >= sv + width || pv <= sv - width;
        case 4: return pv > sv - width && pv < sv + width;
        case 5: return pv >= set;
        case 6: return pv <= set;
        case 7: return inputs.segment != 0 && inputs.segment == set_raw;
        default: return false;  // 0 = no alarm; 8-19 not modelled (see the header)
    }
}

}  // namespace loopwire::device::models
