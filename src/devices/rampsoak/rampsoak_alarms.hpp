#pragma once
// The three alarms of the ramp/soak controller: AL1-AL3 set values (§7, 0003H-0005H) and
// their modes ALD1-ALD3 (§7, 0050H/0052H/0054H, "0~19"), shown on the AL1-AL3 LEDs of OBIT
// (§7, 0088H, bits 3-5).
//
// The manual prints the mode range 0~19 but no table of what each code does. The model
// implements the codes program controllers of this register layout conventionally use:
//   0 no alarm
//   1 deviation high      PV >= SV + AL
//   2 deviation low       PV <= SV + AL   (AL set negative)
//   3 deviation high/low  PV >= SV + |AL| or PV <= SV - |AL|
//   4 band                SV - |AL| < PV < SV + |AL|   (on inside the band)
//   5 process high        PV >= AL
//   6 process low         PV <= AL
//   7 segment             the running program segment (SEG) equals AL
// Codes 8-19 are not modelled and leave the alarm off. SV is the working set point (the
// program's while a program runs). Alarm hysteresis (HYSA, 0056H) is not applied: its printed
// code list (0000H-1111H) is copied from SET1 and gives no value to apply; alarm time (ALTn)
// is not modelled either.
#include <cstdint>

namespace loopwire::device::models {

struct AlarmInputs {
    double process_value = 0;    // engineering units
    double set_point = 0;        // working set point, engineering units
    std::uint16_t segment = 0;   // SEG: running segment number, 0 when no program runs
};

// Whether an alarm of `mode` with set value `set` (engineering units; raw for mode 7) is on.
bool alarm_on(std::uint16_t mode, double set, std::int16_t set_raw, const AlarmInputs& inputs);

}  // namespace loopwire::device::models
