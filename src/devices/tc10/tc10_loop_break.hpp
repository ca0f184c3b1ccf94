#pragma once
// The TC10's loop break alarm, LBA (tc10-modbus-im05c01e81-03.ru.txt §5.3.6 #52–#55; state
// §5.1 10A bit 9, §5.2 10B; routed to outputs by o<n>AL +8, §5.3.2 #17).
#include <cstdint>
#include <optional>

namespace loopwire::device::models::tc10 {

// LbcA (#55) codes.
inline constexpr std::uint16_t loop_break_when_up = 0;    // uP: Pout = 100 %
inline constexpr std::uint16_t loop_break_when_down = 1;  // dn: Pout = -100 %

struct LoopBreakSettings {
    double time = 0;              // LbAt, seconds; 0 = oFF
    double delta = 0;             // LbAS, engineering units
    std::uint16_t condition = 0;  // LbcA
};

class LoopBreakAlarm {
public:
    // Advances by `seconds`: `output` is the control output in % (-100…100), `measured` the
    // measurement, nullopt while it is in error.
    void update(double seconds, const LoopBreakSettings& settings, double output, std::optional<double> measured);
    bool active() const { return active_; }

private:
    int direction_ = 0;     // +1 timing at +100 %, -1 at -100 %, 0 not timing
    double reference_ = 0;  // the measurement the process must move away from by LbAS
    double timed_ = 0;      // seconds without that answer
    bool active_ = false;
};

}  // namespace loopwire::device::models::tc10
