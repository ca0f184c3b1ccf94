#pragma once
// The rampsoak behaviour model: what the manual (rampsoak-pid-rtu-ascii-linking.en.txt) says
// the device does beyond its profile data, and what a believable controller needs where the
// manual is silent (each such choice is stated beside the code and tested):
// - Linking M writes RAM only, W writes RAM and EEPROM (§6.2); Modbus writes are saved.
// - The protocol selection PSL and the other Level-3 words start as §1 gives them.
// - PTN runs the ramp/soak program (rampsoak_program.hpp); SEG and TIMR show it.
// - A heated chamber (process/thermal_plant.hpp) under PID control (P1, I1, D1, HYS1; output
//   limited by OUTL and the running segment's OUTn) gives PV and OUT%.
// - Alarms (rampsoak_alarms.hpp) and the OBIT LED/message word follow the process.
// - UNIT (0066H) sets the unit of PV and SV, PVOS (0065H) offsets the PV, and LSPL/USPL
//   (004CH/004DH) bound the set points a write may give (rampsoak_limits.cpp).
// - No register reaches a program hold or manual output (see after_write).
#include <array>
#include <optional>

#include "devices/rampsoak/rampsoak_program.hpp"
#include "simulation/process/pid_controller.hpp"
#include "simulation/process/thermal_plant.hpp"
#include "simulation/simulated_device.hpp"

namespace loopwire::device::models {

class RampSoakSimulator : public SimulatedDevice {
public:
    RampSoakSimulator(std::shared_ptr<const Profile> profile, SimulationEnvironment environment);

    std::vector<std::string> fault_names() const override { return {"open-input"}; }

protected:
    std::uint16_t on_read(const Parameter& parameter, std::uint16_t stored) override;
    void after_write(const Parameter& parameter, std::uint16_t raw) override;
    std::optional<std::uint8_t> accept_write(const Parameter& parameter, std::uint16_t raw,
                                             const RawValues& known) override;  // rampsoak_limits.cpp
    Persistence persistence_of(std::uint8_t function) const override;
    void step_process(double seconds) override;
    void apply_fault(const std::string& fault) override;
    void describe_line() override;  // rampsoak_line.cpp

private:
    struct SegmentCells {
        MemoryCell* set_point = nullptr;
        MemoryCell* run_time = nullptr;
        MemoryCell* output_limit = nullptr;
    };
    using PatternCells = std::array<SegmentCells, segments_per_pattern>;

    void find_cells();
    void set_factory_values();
    double scale() const;
    double engineering(const MemoryCell* cell) const;
    std::uint16_t display_raw(double engineering) const;
    ProgramPattern pattern() const;
    double set_point() const;
    double in_configured_unit(double celsius) const;
    double measured_value() const;
    bool is_set_point(const Parameter& parameter) const;
    double output_limit() const;
    process::PidSettings pid_settings() const;
    double shown_process_value();
    std::uint16_t status_word(double process_value) const;
    void publish();

    process::ThermalPlant plant_;
    process::PidController pid_;
    RampSoakProgram program_;
    double output_ = 0;        // % of the heating output
    bool input_open_ = false;  // "open-input" fault: sensor break

    MemoryCell* set_value_ = nullptr;
    MemoryCell* output_limit_ = nullptr;
    MemoryCell* program_pattern_ = nullptr;
    MemoryCell* program_segment_ = nullptr;
    MemoryCell* program_countdown_ = nullptr;
    std::array<PatternCells, 2> patterns_{};
    MemoryCell* proportional_band_ = nullptr;
    MemoryCell* integral_time_ = nullptr;
    MemoryCell* derivative_time_ = nullptr;
    MemoryCell* hysteresis_ = nullptr;
    MemoryCell* decimal_point_ = nullptr;
    MemoryCell* lower_set_point_limit_ = nullptr;
    MemoryCell* upper_set_point_limit_ = nullptr;
    MemoryCell* pv_compensation_ = nullptr;
    MemoryCell* unit_ = nullptr;
    std::array<MemoryCell*, 3> alarm_sets_{};
    std::array<MemoryCell*, 3> alarm_modes_{};
    MemoryCell* output_percentage_ = nullptr;
    MemoryCell* status_ = nullptr;
    MemoryCell* process_value_ = nullptr;
};

}  // namespace loopwire::device::models
