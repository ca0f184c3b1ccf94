#pragma once
// Raw words <-> engineering values: two's complement or unsigned, decimals fixed or read from
// another parameter, enum labels, named bits, and special values decoded to named states.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "common/result.hpp"
#include "profile/profile.hpp"

namespace loopwire::device {

// The raw words known so far, by parameter name: what decimals and bounds are looked up in.
using RawValues = std::map<std::string, std::uint16_t, std::less<>>;

struct EngineeringValue {
    // null (monostate) when `status` names a special state; a number in engineering units; an
    // enum label; or, for bit fields, each named bit's state.
    std::variant<std::monostate, double, std::string, std::map<std::string, bool>> value;
    // "ok"; the special state ("not-available", "under-range", ...); or "unknown-label" for an
    // enum word whose raw value the profile gives no label (reserved or undocumented codes):
    // the number is then the value, and the status tells a reader it is not a listed code.
    std::string status = "ok";
    std::uint16_t raw = 0;
    // The engineering unit at the time of the reading: fixed, or what the configuration words it
    // follows said (unit_of); empty for codes, counts, labels and bits.
    std::string unit;
    // The decimal places the device gave the number at the time of reading (fixed, or what its
    // decimals word said), so its text keeps them: "0.85" and "1.00" %C, never "1". None for
    // labels, bits, special states and values made by hand, whose text shows what they hold.
    std::optional<int> decimals = std::nullopt;
};

// What unit_of says when the words a unit follows were not read, or hold a value the profile
// does not list: the unit is not known, which is not the same as having none.
inline constexpr const char* unknown_unit = "?";

// EngineeringValue::status of an enum word whose code the profile does not list.
inline constexpr const char* unknown_label_status = "unknown-label";

// The unit of `parameter`'s values given what is known: its fixed unit, or the first of its
// unit_from rules whose word is known and holds a listed value (compared as int16 and uint16);
// unknown_unit when it has rules and none applies; empty when it has no unit.
std::string unit_of(const Parameter& parameter, const RawValues& known);

// Decimals for `parameter` given what is known; an error names the parameter whose value is
// needed but missing (or out of 0..4).
Result<int> decimals_of(const Parameter& parameter, const RawValues& known);

// The value carries unit_of(parameter, known). Special values are checked first, the raw word compared both as int16 and as uint16 (the
// profile writes them -32768..65535); the first match wins, so a parameter's own specials beat
// the profile's word_specials (AC20 8000h reads as not-available, its first meaning). Then by
// type: int16/uint16 scaled by the decimals (a label instead where the profile gives one for
// that raw, as for the AC20 lock words); enum -> label; bitfield -> each named bit; bool -> its
// label where the profile gives 0/1 labels, else the number 0 or 1 (a raw above 1 is an error).
Result<EngineeringValue> decode_value(const Parameter& parameter, std::uint16_t raw, const RawValues& known);

// Text from a user ("250.5", "-12.5", an enum label, "on"/"off"/1/0 for bools, a special
// state's name such as "off") to the raw word. Checks access (writable), type, decimals
// (250.55 with 1 decimal is refused, not rounded), and range (fixed, or bounded by other
// parameters in `known`; a bound whose parameter is unknown is reported as such). Every error
// is ErrorKind::usage and names the parameter and the limit. A bound set by another parameter
// is decoded with that parameter's own type, decimals and specials (Parameter::bound_sources).
// Labels and special state names are legal values by definition and skip the range check.
Result<std::uint16_t> encode_value(const Parameter& parameter, std::string_view text, const RawValues& known);

// Whether a device keeps `raw` for `parameter`: the value is decoded and checked the way
// encode_value checks a user's value (type, decimals, range, bounds set by other parameters in
// `known`). Special states are legal by definition; an enum code the profile does not list is
// not a setting the device has (TC10 §4.4 B.2, ramp/soak §4.6 "out of setting range").
// Access is not checked. Simulators use it for range-checked writes, restore for write order.
bool raw_in_range(const Parameter& parameter, std::uint16_t raw, const RawValues& known);

// A number's limits in engineering units as the device holds them now (every front
// shows the same numbers): a fixed bound (display counts scaled by the present decimals), or
// the value of the parameter that bounds it, decoded as encode_value checks a write against it.
// None where there is no bound, or its word (or the decimals it needs) is not in `known`.
struct ValueLimits {
    std::optional<double> min;
    std::optional<double> max;
    bool operator==(const ValueLimits&) const = default;
};
ValueLimits limits_of(const Parameter& parameter, const RawValues& known);

// Which parameters a value of `parameter` depends on (decimals source, unit_from words, range
// bounds), so a
// caller can read them first. A bound's own decimals source is included too (from
// Parameter::bound_sources), listed before the bound.
std::vector<std::string> dependencies_of(const Parameter& parameter);

// The inverse of decode_value, without encode_value's access and range checks (simulators,
// tests): the raw word for a decoded value. A special state gives its raw (the first with that
// name), a label its key, a number is scaled by the decimals; bit-field bits the map does not
// name are taken from value.raw.
Result<std::uint16_t> raw_of(const Parameter& parameter, const EngineeringValue& value, const RawValues& known);

// A decoded value as text that encode_value accepts back: numbers with the parameter's decimals
// ("137.0"), labels, a special state's name ("not-available"), bit fields as the set bits'
// names joined by '+' ("alarm_1+alarm_3"; "bit7" for a bit without a name; "none").
Result<std::string> format_value(const Parameter& parameter, const EngineeringValue& value, const RawValues& known);

}  // namespace loopwire::device
