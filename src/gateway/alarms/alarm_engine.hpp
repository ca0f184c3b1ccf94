#pragma once
// The gateway's alarms: limit alarms on polled values ([[alarms.limits]]) and the communication
// alarms every device has (silent, line down, wrong device), each in the states ISA-18.2 and
// IEC 62682 name: normal, active-unacknowledged, active-acknowledged, returned-unacknowledged
// (cleared before anyone acknowledged it), shelved (for a while, ends by itself) and
// out-of-service.
//
// A plain class: fed values, device statuses and operators' actions, each with the time it
// happened, and asked with tick(now) for what the passing of time did (delays, shelving that
// ends). Each call returns the transitions it made, for the journal and the fronts. It has no
// thread and reads no clock, so tests run it on virtual time; the gateway's AlarmService
// (alarm_service.hpp) feeds it on the engine's loop.
//
// One alarm per source, however a value chatters: a limit alarm raised stays raised until the
// value is back past the limit by the deadband, and a raise (a clear) takes effect only once the
// condition has held for on_delay (off_delay). A value that was not read (no reply, stale, a
// special state) neither raises nor clears: the alarm keeps its state and a delay under way
// starts again with the next reading.
#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "client/device_status.hpp"

namespace loopwire::gateway::alarms {

using Time = std::chrono::system_clock::time_point;
using std::chrono::milliseconds;

enum class LimitKind { high, high_high, low, low_low, deviation };
enum class Severity { low, medium, high, critical };
enum class AlarmState { normal, active_unacknowledged, active_acknowledged, returned_unacknowledged, shelved, out_of_service };
enum class CommunicationKind { silent, line_down, wrong_device };

std::string_view name_of(LimitKind kind);
std::string_view name_of(Severity severity);
std::string_view name_of(AlarmState state);      // "active-unacknowledged", ...
std::string_view name_of(CommunicationKind kind);  // "silent", "line_down", "wrong_device"
std::optional<LimitKind> limit_kind_named(std::string_view name);
std::optional<Severity> severity_named(std::string_view name);
std::optional<AlarmState> state_named(std::string_view name);
// Whether the alarm is active in that state (shown as raised, counted in /metrics' gauge).
bool is_active(AlarmState state);

// One limit alarm as configured ([[alarms.limits]]).
struct LimitAlarm {
    std::string name;       // unique on its device: "temperature_high" unless configured
    std::string device;
    std::string parameter;  // what is compared
    std::string setpoint;   // deviation only: the parameter PV is compared with
    LimitKind kind = LimitKind::high;
    double limit = 0;       // the limit; for deviation, the largest |PV - SP| allowed
    double deadband = 0;    // how far back past the limit the value must go to clear
    milliseconds on_delay{0};
    milliseconds off_delay{0};
    Severity severity = Severity::medium;
    std::string message;  // "" : a message made from the rest ("temperature above 250")

    bool operator==(const LimitAlarm&) const = default;
};

// "DEVICE.NAME": how the API, the journal and the log name an alarm.
std::string alarm_id(std::string_view device, std::string_view name);

// An alarm's state changed (or it was acknowledged, shelved, ...): a row of the journal.
struct AlarmTransition {
    Time time;
    std::string id;  // "oven.temperature_high"
    std::string device;
    std::string name;
    std::string parameter;  // empty for a communication alarm
    AlarmState state = AlarmState::normal;
    std::optional<double> value;  // the value that raised or cleared it, if any
    std::string unit;
    Severity severity = Severity::medium;
    std::string message;
    std::string user;     // who acknowledged, shelved, ... (empty: the engine itself)
    std::string comment;
    std::optional<Time> shelved_until;  // with `shelved`
};

// What the API shows of one alarm now.
struct AlarmView {
    std::string id;
    std::string device;
    std::string name;
    std::string parameter;
    std::string kind;  // "high", ..., "silent", ...
    AlarmState state = AlarmState::normal;
    Time since{};  // when it entered that state (the epoch: never left normal)
    std::optional<double> value;
    std::string unit;
    Severity severity = Severity::medium;
    std::string message;
    std::optional<Time> shelved_until;
};

// An alarm's state as the journal last recorded it: restored at start.
struct RestoredState {
    AlarmState state = AlarmState::normal;
    Time since{};
    std::optional<double> value;
    std::optional<Time> shelved_until;
};

using Transitions = std::vector<AlarmTransition>;

class AlarmEngine {
public:
    // The limit alarms, and the devices whose communication alarms there are.
    AlarmEngine(std::vector<LimitAlarm> limits, const std::vector<std::string>& devices,
                Severity communication_severity = Severity::high);

    // Sets each alarm's state as the journal left it (before anything is fed).
    void restore(const std::map<std::string, RestoredState>& states);

    // A reading of device.parameter: `value` with `status` ("ok", or why there is none) and unit.
    Transitions feed(std::string_view device, std::string_view parameter, std::optional<double> value,
                     std::string_view status, std::string_view unit, Time now);
    // The device's own status changed: its communication alarms follow it.
    Transitions feed_device(std::string_view device, device::DeviceStatus status, Time now);
    // Delays and shelving that end by `now`.
    Transitions tick(Time now);

    // The operator's actions; an unknown id or a state that takes no such action is an error
    // (the message says why), with no transition.
    struct Outcome {
        Transitions transitions;
        std::string refusal;  // empty: done
        bool unknown = false;  // no such alarm
    };
    Outcome acknowledge(std::string_view id, std::string_view user, std::string_view comment, Time now);
    Outcome shelve(std::string_view id, milliseconds duration, std::string_view user, std::string_view comment, Time now);
    Outcome unshelve(std::string_view id, std::string_view user, std::string_view comment, Time now);
    Outcome remove_from_service(std::string_view id, std::string_view user, std::string_view comment, Time now);
    Outcome return_to_service(std::string_view id, std::string_view user, std::string_view comment, Time now);

    std::vector<AlarmView> views() const;  // every alarm, in configuration order
    std::size_t size() const { return alarms_.size(); }

private:
    struct Alarm {
        std::string id;
        std::string device;
        std::string name;
        std::string parameter;
        std::string setpoint;
        std::string kind;
        std::optional<LimitKind> limit_kind;            // none: a communication alarm
        std::optional<CommunicationKind> communication;
        double limit = 0;
        double deadband = 0;
        milliseconds on_delay{0};
        milliseconds off_delay{0};
        Severity severity = Severity::medium;
        std::string message;
        // The condition after deadband and delays, and whether it was acknowledged since it last rose.
        bool active = false;
        bool acknowledged = true;
        bool out_of_service = false;
        std::optional<Time> shelved_until;
        // The latest reading's verdict, and since when it has differed from `active` (a delay running).
        std::optional<bool> wanted;
        std::optional<Time> wanted_since;
        std::optional<double> pv;
        std::optional<double> sp;
        std::optional<double> value;  // the value when the state last changed
        std::string unit;
        AlarmState state = AlarmState::normal;
        Time since{};
        bool timed = false;  // in timed_
    };

    static AlarmState state_of(const Alarm& alarm);
    Alarm* find(std::string_view id);
    void evaluate(Alarm& alarm, Time now, Transitions& out);
    void watch(Alarm& alarm);  // tick() looks at it until its delay or shelving is over
    void settle(Alarm& alarm, Time now, Transitions& out);
    void record(Alarm& alarm, Time now, Transitions& out, std::string_view user = {}, std::string_view comment = {});
    std::optional<bool> condition(const Alarm& alarm) const;

    std::vector<Alarm> alarms_;
    // Which alarms read a parameter (as PV or SP), by "device\nparameter"; and a device's communication alarms.
    std::map<std::string, std::vector<std::size_t>, std::less<>> by_parameter_;
    std::map<std::string, std::vector<std::size_t>, std::less<>> by_device_;
    // Alarms with a delay running or shelved until a time: what tick() looks at.
    std::vector<std::size_t> timed_;
};

}  // namespace loopwire::gateway::alarms
