#pragma once
// One device on a link, read and written by parameter name in engineering units.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <loopwire/link.hpp>

namespace loopwire {

// What a reading is: a value, a state the device reports instead of one, or a failure.
enum class ValueStatus {
    ok,             // a value as the device means it
    special_state,  // the device reports a state instead of a value (`status` names it: "under-range")
    unlisted_code,  // an enum word whose code the profile does not list ("unknown-label"); `number` holds it
    error,          // not read: `error` says why
};

struct Reading {
    std::string name;              // the parameter's name ("measured_value")
    std::string mnemonic;          // as the device's display shows it ("rV")
    std::optional<double> number;  // the value in engineering units, when it is a number
    std::string text;              // as people read it: "137.0", "heating", "—" for special states
    // "°C", "%", "s" as the device is configured (a TC10's temperatures follow its unit word:
    // °C or °F); empty when the value has no unit, "?" when the word it follows could not be read.
    std::string unit;
    // The limits a write is checked against, in engineering units as the device holds them now
    // (a fixed range scaled by the present decimals, or the value of the parameter that bounds
    // it: a set point between its low and high limits); none where there is no limit.
    std::optional<double> min;
    std::optional<double> max;
    ValueStatus state = ValueStatus::error;
    std::string status;            // state as text: "ok", the special state's name, "unknown-label" or "error"
    std::uint16_t raw = 0;         // the word on the wire
    std::string error;             // why the read failed, when status is "error"

    bool failed() const { return state == ValueStatus::error; }
};

class Device {
public:
    // `device` names a profile and the unit id it answers at: "tc10@3" for a built-in profile
    // (ac20, rampsoak, tc10), or a profile file, "profiles/my_device.json@5". Throws
    // Failure(Kind::usage) for an unknown profile, an invalid profile file or a bad unit id.
    Device(Link link, const std::string& device);

    std::string profile_id() const;
    int unit() const;

    // Reads one parameter, named by its name or mnemonic. Throws Failure when it cannot be
    // read (no reply, an exception reply) or the name is unknown or names a group.
    Reading read(const std::string& name);

    // Reads names, mnemonics or groups ("all": everything readable) in as few requests as the
    // profile allows. Unknown names throw; a request that fails marks its parameters' readings
    // as failed (status "error" with the reason) and the others are still read.
    std::vector<Reading> read(const std::vector<std::string>& names);

    // Writes a value given as the command line takes it ("150.5", an enum label, "on"). The
    // value is checked first (writable, type, decimals, range - bounds set by other parameters
    // are read from the device); nothing is sent when it is invalid (Failure, Kind::usage).
    void write(const std::string& name, const std::string& value);

    // Several NAME, VALUE pairs: every value is checked before anything is sent, then they are
    // written in as few requests as the profile allows, in the order given.
    void write(const std::vector<std::pair<std::string, std::string>>& assignments);

    struct State;

private:
    std::shared_ptr<State> state_;
};

}  // namespace loopwire
