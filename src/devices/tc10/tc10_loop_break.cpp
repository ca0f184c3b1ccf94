#include "devices/tc10/tc10_loop_break.hpp"

namespace loopwire::device::models::tc10 {
namespace {

// A full output, as the controller computes it: 100 % (or -100 %) less rounding.
constexpr double saturated = 100.0 - 1e-9;

// #55 LbcA "Условие включения LBA: 0 = uP = Активна, когда Pout = 100 %; 1 = dn = Активна,
// когда Pout = -100 %; 2 = both = Активна в обоих случаях" (LBA enabled when the output is at
// 100 %, at -100 %, or both). The direction the full output pushes the measurement: +1 up
// (heating), -1 down (cooling), 0 when the LBA does not watch this output.
int watched_direction(double output, std::uint16_t condition) {
    if (output >= saturated && condition != loop_break_when_down) return 1;
    if (output <= -saturated && condition != loop_break_when_up) return -1;
    return 0;
}

}  // namespace

// #52 LbAt "Время сигнализации обрыва цепи (LBA) … 0 (oFF) … 9999 (с)" (loop break alarm time) and
// #54 LbAS "Мера разности, используемая сигнализацией обрыва цепи" (the difference the LBA uses).
// The manual names the settings only. Chosen, as loop break alarms usually work: while the
// output stays at the full value LbcA watches, the measurement must move by LbAS in the
// direction the output pushes within every LbAt seconds; when it does not, the LBA is on. It
// goes off as soon as the measurement answers by LbAS or the output leaves the full value. A
// measurement error stops it (the sensor fault has its own indication). #53 LbSt, the
// difference used during soft start, does not apply: soft start (#73–#75) is not simulated.
void LoopBreakAlarm::update(double seconds, const LoopBreakSettings& settings, double output,
                            std::optional<double> measured) {
    const int direction = watched_direction(output, settings.condition);
    if (settings.time <= 0 || !measured || direction == 0) {
        *this = {};
        return;
    }
    if (direction != direction_ || (*measured - reference_) * direction >= settings.delta) {
        direction_ = direction;
        reference_ = *measured;
        timed_ = 0;
        active_ = false;
        return;
    }
    timed_ += seconds;
    if (timed_ >= settings.time) active_ = true;
}

}  // namespace loopwire::device::models::tc10
