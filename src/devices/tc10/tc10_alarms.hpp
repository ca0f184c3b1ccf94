#pragma once
// One TC10 alarm (AL1, AL2, AL3) computed from the process: its type, hysteresis, delay,
// function (latched, acknowledgeable) and whether standby or a measurement error inhibit it
// (tc10-modbus-im05c01e81-03.ru.txt §5.3.3–5.3.5, #28–#51; reset and acknowledge: §5.1 13A, 14A).
#include <cstdint>

namespace loopwire::device::models::tc10 {

// AL1t / AL2t / AL3t codes (§5.3.3 #28).
enum class AlarmType : std::uint16_t {
    none = 0,
    absolute_low = 1,           // LoAb
    absolute_high = 2,          // HiAb
    band_outside = 3,           // LHAo: alarm outside [ALnL, ALnH]
    band_inside = 4,            // LHAi: alarm inside [ALnL, ALnH]
    sensor_break = 5,           // SE.br
    deviation_low = 6,          // LodE
    deviation_high = 7,         // HidE
    relative_band_outside = 8,  // LHdo: alarm outside [SP + ALnL, SP + ALnH]
    relative_band_inside = 9,   // LHdi: alarm inside [SP + ALnL, SP + ALnH]
};

// Abn function bits (§5.3.3 #29).
inline constexpr std::uint16_t function_masked_at_power_on = 1;    // +1 not active at power-on
inline constexpr std::uint16_t function_latched = 2;               // +2 manual reset
inline constexpr std::uint16_t function_acknowledgeable = 4;       // +4
inline constexpr std::uint16_t function_masked_at_sp_change = 8;   // +8 relative: not at SP change

// ALno (§5.3.3 #35): bit 0 = enabled in standby, bit 1 = enabled in the out-of-range state.
inline constexpr std::uint16_t enabled_in_standby = 1;
inline constexpr std::uint16_t enabled_out_of_range = 2;

// The alarm's parameters in engineering units (already scaled by dP).
struct AlarmSettings {
    AlarmType type = AlarmType::none;
    std::uint16_t function = 0;
    double low_limit = 0;   // ALnL
    double high_limit = 0;  // ALnH
    double threshold = 0;   // ALn
    double hysteresis = 0;  // HALn
    double delay = 0;       // ALnd, seconds
    std::uint16_t enable = 0;  // ALno
};

// What the alarm watches. On a measurement error `measured` is +infinity for over-range and
// -infinity for under-range, so the thresholds compare the way the reading went.
struct AlarmInputs {
    double measured = 0;
    double set_point = 0;
    bool measurement_error = false;
    bool standby = false;
};

class Alarm {
public:
    // Advances by `seconds` of process time.
    void update(double seconds, const AlarmSettings& settings, const AlarmInputs& inputs);
    // What the alarm status words and the alarm outputs show.
    bool active() const { return (raised_ || latched_) && !acknowledged_; }
    // Word 13 = 1: a latched alarm whose condition has cleared goes off.
    void reset();
    // Word 14 = 1: an acknowledgeable alarm (`function` = ALn's Abn now) goes off while its
    // condition lasts.
    void acknowledge(std::uint16_t function);

private:
    bool condition(const AlarmSettings& settings, const AlarmInputs& inputs) const;
    void update_mask(const AlarmSettings& settings, const AlarmInputs& inputs);
    void clear();

    bool started_ = false;
    double last_set_point_ = 0;
    bool masked_ = false;  // +1 / +8: held off until the condition has once been absent

    bool condition_ = false;  // the type's condition, with hysteresis
    double held_ = 0;         // seconds the condition has lasted (delay)
    bool raised_ = false;     // the condition has lasted the delay
    bool latched_ = false;
    bool acknowledged_ = false;
};

}  // namespace loopwire::device::models::tc10
