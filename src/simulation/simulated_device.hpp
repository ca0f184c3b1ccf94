#pragma once
// One simulated controller served from its profile: the rules the profile data states
// (function codes, per-request limits, unmapped addresses, mirrors, read-only words, ranges,
// special values, broadcast, numbering alternatives). Device behaviour the data cannot express
// (AC20 modes and locks, TC10 alarms, the ramp/soak program, the process each one controls)
// belongs in a model subclass (devices/<id>/) that overrides the hooks below.
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "simulation/device_memory.hpp"
#include "profile/profile.hpp"
#include "simulation/simulation_environment.hpp"
#include "session/unit_handler.hpp"

namespace loopwire::device {

class SimulatedDevice : public session::RequestHandler {
public:
    explicit SimulatedDevice(std::shared_ptr<const Profile> profile, SimulationEnvironment environment = {});

    // Time first (the process catches up with the clock), then the model's own say
    // (intercept), then silence and limits before decoding: the AC20 says nothing at all to a
    // function code it does not implement, and a count over a device's limit gets its own
    // exception.
    std::optional<Bytes> handle(ByteView request_pdu, bool broadcast) override;

    const Profile& profile() const { return *profile_; }

    // Where the device answers now, when its own words moved it off the unit it is served under
    // (session::UnitHandler::answers_as); nullopt until then.
    std::optional<std::uint8_t> answers_as() const override;

    static constexpr double max_process_step = 0.1;  // seconds of process time per model step (the grid)

    // Brings the process up to the environment's clock without a request (monitors, tests).
    void advance();

    // --fault: a named sensor or device fault ("open-input", ...), or "none" to clear them.
    // Unknown names are a usage error that lists the faults this device knows.
    Result<void> inject_fault(const std::string& fault);
    virtual std::vector<std::string> fault_names() const { return {}; }

    // --state: non-volatile contents by parameter name, and their reload at start. After a
    // reload the words that describe the line are set from the line again (describe_line): a
    // device answering as unit N at some settings reports those, whatever was saved.
    RawValues saved_values() const;
    std::vector<std::string> load_saved(const RawValues& saved);
    // What the device keeps at power-off besides its parameters (the AC20's mode and
    // local/remote state, Note 5), by name; its reload at start, after load_saved. Names the
    // model does not know are ignored. A change of it counts in saved_generation().
    RawValues saved_condition() const;
    void load_condition(const RawValues& condition);
    std::uint64_t saved_generation() const;

    // session::UnitHandler: a frame for any unit of the line, or bytes failing their check,
    // went past (the AC20's remote state lives on line activity, Note 5).
    void line_activity() override;

protected:
    codec::Reply serve(const codec::Request& request) override;

    // Hooks for per-device models, called with the device locked.
    // A reply (or silence, nullopt inside) decided before any profile rule, or nullopt to go on.
    virtual std::optional<std::optional<Bytes>> intercept(ByteView request_pdu, bool broadcast);
    // An exception code to refuse a write the profile's rules allow (modes, locks), or nullopt.
    virtual std::optional<std::uint8_t> accept_write(const Parameter& parameter, std::uint16_t raw,
                                                     const RawValues& known);
    // What a read returns for a stored word (process values, bits that clear when read).
    virtual std::uint16_t on_read(const Parameter& parameter, std::uint16_t stored);
    // After a write has been stored.
    virtual void after_write(const Parameter& parameter, std::uint16_t raw);
    // Where a write from `function` lands (ramp/soak: Linking M, served as FC6, is RAM only).
    virtual Persistence persistence_of(std::uint8_t function) const;
    // Runs the process and timers forward by `seconds` of process time (already scaled by
    // --speed), in steps of max_process_step (longer ones only after a very long pause).
    virtual void step_process(double seconds);
    // Applies a fault named in fault_names(), or "none".
    virtual void apply_fault(const std::string& fault);
    // Sets the words in which the device describes its line (address, baud rate, byte format,
    // protocol) from the environment's unit, framing and serial settings. Models call it at the
    // end of their constructor; load_saved calls it again.
    virtual void describe_line() {}
    // saved_condition() / load_condition() / line_activity(), with the device locked.
    virtual RawValues condition_at_power_off() const { return {}; }
    virtual void restore_condition(const RawValues& /*condition*/) {}
    virtual void on_line_activity() {}
    // The model's condition_at_power_off() changed: the state file is due to be saved.
    void condition_changed() { ++condition_generation_; }

    // From the next request on, answer at `unit` (0: hear nothing on this line), or again at the
    // unit the device is served under (nullopt).
    void answer_as(std::optional<std::uint8_t> unit);

    DeviceMemory& memory() { return memory_; }
    const DeviceMemory& memory() const { return memory_; }
    const SimulationEnvironment& environment() const { return environment_; }
    std::mt19937_64& random() { return random_; }
    // Process seconds since the device started (scaled by --speed).
    double process_time() const { return process_time_; }

    // By profile name; a name the profile lacks is a programming error in the model (asserts).
    std::uint16_t value(std::string_view name) const;
    void set_value(std::string_view name, std::uint16_t raw, Persistence persistence = Persistence::ram_only);

private:
    std::optional<Bytes> refuse(std::uint8_t function, std::uint8_t code) const;
    std::optional<std::uint8_t> over_limit(ByteView request_pdu) const;
    Table table_for(std::uint8_t function) const;
    std::uint16_t numbering_offset() const;
    MemoryCell* find(Table table, std::uint16_t wire_address);
    codec::Reply read(const codec::Request& request);
    codec::Reply write(const codec::Request& request);
    void advance_locked();

    std::shared_ptr<const Profile> profile_;
    SimulationEnvironment environment_;
    DeviceMemory memory_;
    std::mt19937_64 random_;
    SimulationClock::time_point last_advance_;
    double process_time_ = 0;          // walked so far
    double pending_process_time_ = 0;  // elapsed but shorter than a grid step
    std::uint64_t condition_generation_ = 0;  // condition_changed()
    mutable std::mutex mutex_;  // one device, several links or TCP connections
    std::atomic<int> answering_unit_{-1};  // answers_as(): -1 none, else 0..255 (read by the slave unlocked)
};

}  // namespace loopwire::device
