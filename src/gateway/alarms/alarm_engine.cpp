#include "gateway/alarms/alarm_engine.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace loopwire::gateway::alarms {
namespace {

constexpr std::pair<LimitKind, std::string_view> limit_kinds[] = {{LimitKind::high, "high"},
                                                                   {LimitKind::high_high, "high_high"},
                                                                   {LimitKind::low, "low"},
                                                                   {LimitKind::low_low, "low_low"},
                                                                   {LimitKind::deviation, "deviation"}};
constexpr std::pair<Severity, std::string_view> severities[] = {
    {Severity::low, "low"}, {Severity::medium, "medium"}, {Severity::high, "high"}, {Severity::critical, "critical"}};
constexpr std::pair<AlarmState, std::string_view> states[] = {
    {AlarmState::normal, "normal"},
    {AlarmState::active_unacknowledged, "active-unacknowledged"},
    {AlarmState::active_acknowledged, "active-acknowledged"},
    {AlarmState::returned_unacknowledged, "returned-unacknowledged"},
    {AlarmState::shelved, "shelved"},
    {AlarmState::out_of_service, "out-of-service"}};
constexpr std::pair<CommunicationKind, std::string_view> communications[] = {
    {CommunicationKind::silent, "silent"}, {CommunicationKind::line_down, "line_down"}, {CommunicationKind::wrong_device, "wrong_device"}};

template <typename T, std::size_t N>
std::string_view lookup_name(const std::pair<T, std::string_view> (&table)[N], T value) {
    for (const auto& [known, name] : table) {
        if (known == value) return name;
    }
    return "?";
}

template <typename T, std::size_t N>
std::optional<T> lookup_value(const std::pair<T, std::string_view> (&table)[N], std::string_view name) {
    for (const auto& [known, text] : table) {
        if (text == name) return known;
    }
    return std::nullopt;
}

std::string parameter_key(std::string_view device, std::string_view parameter) {
    std::string key;
    key.reserve(device.size() + parameter.size() + 1);
    key.append(device).append(1, '\n').append(parameter);
    return key;
}

std::string limit_message(const LimitAlarm& alarm) {
    switch (alarm.kind) {
        case LimitKind::high: return fmt::format("{} above {}", alarm.parameter, alarm.limit);
        case LimitKind::high_high: return fmt::format("{} above {} (high-high)", alarm.parameter, alarm.limit);
        case LimitKind::low: return fmt::format("{} below {}", alarm.parameter, alarm.limit);
        case LimitKind::low_low: return fmt::format("{} below {} (low-low)", alarm.parameter, alarm.limit);
        case LimitKind::deviation: return fmt::format("{} more than {} from {}", alarm.parameter, alarm.limit, alarm.setpoint);
    }
    return alarm.parameter;
}

std::string_view communication_message(CommunicationKind kind) {
    switch (kind) {
        case CommunicationKind::silent: return "the device does not answer";
        case CommunicationKind::line_down: return "the device's line is down";
        case CommunicationKind::wrong_device: return "another device answers at the device's address";
    }
    return "";
}

// What a device status says of each communication alarm; none: it says nothing (waiting in
// back-off, stale: no new answer either way).
std::optional<bool> communication_fault(CommunicationKind kind, device::DeviceStatus status) {
    using device::DeviceStatus;
    switch (status) {
        case DeviceStatus::ok:
        case DeviceStatus::partial: return false;
        // One cause, one alarm: a line that is down is not also each of its devices' silence.
        case DeviceStatus::no_reply: return kind == CommunicationKind::silent;
        case DeviceStatus::line_down: return kind == CommunicationKind::line_down;
        case DeviceStatus::wrong_device: return kind == CommunicationKind::wrong_device;
        case DeviceStatus::waiting:
        case DeviceStatus::stale: return std::nullopt;
    }
    return std::nullopt;
}

}  // namespace

std::string_view name_of(LimitKind kind) { return lookup_name(limit_kinds, kind); }
std::string_view name_of(Severity severity) { return lookup_name(severities, severity); }
std::string_view name_of(AlarmState state) { return lookup_name(states, state); }
std::string_view name_of(CommunicationKind kind) { return lookup_name(communications, kind); }
std::optional<LimitKind> limit_kind_named(std::string_view name) { return lookup_value(limit_kinds, name); }
std::optional<Severity> severity_named(std::string_view name) { return lookup_value(severities, name); }
std::optional<AlarmState> state_named(std::string_view name) { return lookup_value(states, name); }

bool is_active(AlarmState state) {
    return state == AlarmState::active_unacknowledged || state == AlarmState::active_acknowledged;
}

std::string alarm_id(std::string_view device, std::string_view name) { return fmt::format("{}.{}", device, name); }

AlarmEngine::AlarmEngine(std::vector<LimitAlarm> limits, const std::vector<std::string>& devices,
                         Severity communication_severity) {
    alarms_.reserve(limits.size() + 3 * devices.size());
    for (const std::string& device : devices) {
        for (const auto& [kind, name] : communications) {
            Alarm alarm;
            alarm.id = alarm_id(device, name);
            alarm.device = device;
            alarm.name = name;
            alarm.kind = name;
            alarm.communication = kind;
            alarm.severity = communication_severity;
            alarm.message = communication_message(kind);
            by_device_[device].push_back(alarms_.size());
            alarms_.push_back(std::move(alarm));
        }
    }
    for (LimitAlarm& limit : limits) {
        Alarm alarm;
        alarm.id = alarm_id(limit.device, limit.name);
        alarm.device = limit.device;
        alarm.name = limit.name;
        alarm.parameter = limit.parameter;
        alarm.setpoint = limit.setpoint;
        alarm.kind = name_of(limit.kind);
        alarm.limit_kind = limit.kind;
        alarm.limit = limit.limit;
        alarm.deadband = limit.deadband;
        alarm.on_delay = limit.on_delay;
        alarm.off_delay = limit.off_delay;
        alarm.severity = limit.severity;
        alarm.message = limit.message.empty() ? limit_message(limit) : limit.message;
        by_parameter_[parameter_key(limit.device, limit.parameter)].push_back(alarms_.size());
        if (limit.kind == LimitKind::deviation && limit.setpoint != limit.parameter) {
            by_parameter_[parameter_key(limit.device, limit.setpoint)].push_back(alarms_.size());
        }
        alarms_.push_back(std::move(alarm));
    }
}

void AlarmEngine::restore(const std::map<std::string, RestoredState>& restored) {
    for (Alarm& alarm : alarms_) {
        const auto found = restored.find(alarm.id);
        if (found == restored.end()) continue;
        const RestoredState& last = found->second;
        alarm.state = last.state;
        alarm.since = last.since;
        alarm.value = last.value;
        alarm.active = is_active(last.state);
        alarm.acknowledged = last.state != AlarmState::active_unacknowledged && last.state != AlarmState::returned_unacknowledged;
        alarm.out_of_service = last.state == AlarmState::out_of_service;
        if (last.state == AlarmState::shelved && last.shelved_until) {
            alarm.shelved_until = last.shelved_until;
            watch(alarm);
        }
    }
}

AlarmState AlarmEngine::state_of(const Alarm& alarm) {
    if (alarm.out_of_service) return AlarmState::out_of_service;
    if (alarm.shelved_until) return AlarmState::shelved;
    if (alarm.active) return alarm.acknowledged ? AlarmState::active_acknowledged : AlarmState::active_unacknowledged;
    return alarm.acknowledged ? AlarmState::normal : AlarmState::returned_unacknowledged;
}

AlarmEngine::Alarm* AlarmEngine::find(std::string_view id) {
    auto found = std::find_if(alarms_.begin(), alarms_.end(), [id](const Alarm& alarm) { return alarm.id == id; });
    return found == alarms_.end() ? nullptr : &*found;
}

// The limit's verdict on the latest readings, with the deadband on the side of clearing: an
// active alarm stays active until the value is back past the limit by the deadband.
std::optional<bool> AlarmEngine::condition(const Alarm& alarm) const {
    if (!alarm.pv) return std::nullopt;
    const double pv = *alarm.pv;
    const double back = alarm.active ? alarm.deadband : 0.0;
    switch (*alarm.limit_kind) {
        case LimitKind::high:
        case LimitKind::high_high: return pv > alarm.limit - back;
        case LimitKind::low:
        case LimitKind::low_low: return pv < alarm.limit + back;
        case LimitKind::deviation:
            if (!alarm.sp) return std::nullopt;
            return std::fabs(pv - *alarm.sp) > alarm.limit - back;
    }
    return std::nullopt;
}

void AlarmEngine::record(Alarm& alarm, Time now, Transitions& out, std::string_view user, std::string_view comment) {
    const AlarmState state = state_of(alarm);
    if (state != alarm.state) alarm.since = now;
    alarm.state = state;
    AlarmTransition transition;
    transition.time = now;
    transition.id = alarm.id;
    transition.device = alarm.device;
    transition.name = alarm.name;
    transition.parameter = alarm.parameter;
    transition.state = state;
    transition.value = alarm.value;
    transition.unit = alarm.unit;
    transition.severity = alarm.severity;
    transition.message = alarm.message;
    transition.user = user;
    transition.comment = comment;
    transition.shelved_until = alarm.shelved_until;
    out.push_back(std::move(transition));
}

// Takes the wanted condition once it has held for its delay; a delay not over yet is left to tick().
void AlarmEngine::settle(Alarm& alarm, Time now, Transitions& out) {
    if (!alarm.wanted || *alarm.wanted == alarm.active) {
        alarm.wanted_since.reset();
        return;
    }
    if (!alarm.wanted_since) {
        alarm.wanted_since = now;
        watch(alarm);
    }
    const milliseconds delay = *alarm.wanted ? alarm.on_delay : alarm.off_delay;
    if (now - *alarm.wanted_since < delay) return;
    alarm.wanted_since.reset();
    alarm.active = *alarm.wanted;
    if (alarm.active) alarm.acknowledged = false;
    alarm.value = alarm.pv;
    // Shelved or out of service, the condition is followed but nobody is told.
    if (state_of(alarm) != alarm.state) record(alarm, now, out);
}

void AlarmEngine::watch(Alarm& alarm) {
    if (alarm.timed) return;
    alarm.timed = true;
    timed_.push_back(static_cast<std::size_t>(&alarm - alarms_.data()));
}

void AlarmEngine::evaluate(Alarm& alarm, Time now, Transitions& out) {
    alarm.wanted = condition(alarm);
    settle(alarm, now, out);
}

Transitions AlarmEngine::feed(std::string_view device, std::string_view parameter, std::optional<double> value,
                              std::string_view status, std::string_view unit, Time now) {
    Transitions out;
    const auto found = by_parameter_.find(parameter_key(device, parameter));
    if (found == by_parameter_.end()) return out;
    // Not read: neither a reason to raise nor to clear (the alarm keeps its state).
    const std::optional<double> reading = status == "ok" ? value : std::nullopt;
    for (const std::size_t index : found->second) {
        Alarm& alarm = alarms_[index];
        if (alarm.parameter == parameter) {
            alarm.pv = reading;
            alarm.unit = unit;
        }
        if (alarm.setpoint == parameter) alarm.sp = reading;
        evaluate(alarm, now, out);
    }
    return out;
}

Transitions AlarmEngine::feed_device(std::string_view device, device::DeviceStatus status, Time now) {
    Transitions out;
    const auto found = by_device_.find(device);
    if (found == by_device_.end()) return out;
    for (const std::size_t index : found->second) {
        Alarm& alarm = alarms_[index];
        const auto fault = communication_fault(*alarm.communication, status);
        if (!fault) continue;
        alarm.wanted = fault;
        settle(alarm, now, out);
    }
    return out;
}

Transitions AlarmEngine::tick(Time now) {
    Transitions out;
    std::vector<std::size_t> due;
    due.swap(timed_);
    for (const std::size_t index : due) {
        Alarm& alarm = alarms_[index];
        alarm.timed = false;
        if (alarm.shelved_until && *alarm.shelved_until <= now) {
            alarm.shelved_until.reset();
            // Back from the shelf, a condition still there is announced again.
            alarm.acknowledged = !alarm.active;
            record(alarm, now, out, "", "shelving ended");
        }
        if (alarm.wanted_since) settle(alarm, now, out);
        if (alarm.shelved_until || alarm.wanted_since) watch(alarm);
    }
    return out;
}

AlarmEngine::Outcome AlarmEngine::acknowledge(std::string_view id, std::string_view user, std::string_view comment, Time now) {
    Outcome outcome;
    Alarm* alarm = find(id);
    if (!alarm) return {{}, fmt::format("no alarm \"{}\"", id), true};
    const AlarmState state = state_of(*alarm);
    if (state != AlarmState::active_unacknowledged && state != AlarmState::returned_unacknowledged) {
        outcome.refusal = fmt::format("alarm \"{}\" is {}: there is nothing to acknowledge", id, name_of(state));
        return outcome;
    }
    alarm->acknowledged = true;
    record(*alarm, now, outcome.transitions, user, comment);
    return outcome;
}

AlarmEngine::Outcome AlarmEngine::shelve(std::string_view id, milliseconds duration, std::string_view user,
                                         std::string_view comment, Time now) {
    Outcome outcome;
    Alarm* alarm = find(id);
    if (!alarm) return {{}, fmt::format("no alarm \"{}\"", id), true};
    if (duration <= milliseconds(0)) {
        outcome.refusal = "a shelving lasts a while: give a duration such as \"1h\"";
        return outcome;
    }
    if (alarm->out_of_service) {
        outcome.refusal = fmt::format("alarm \"{}\" is out-of-service: return it to service first", id);
        return outcome;
    }
    alarm->shelved_until = now + duration;
    watch(*alarm);
    record(*alarm, now, outcome.transitions, user, comment);
    return outcome;
}

AlarmEngine::Outcome AlarmEngine::unshelve(std::string_view id, std::string_view user, std::string_view comment, Time now) {
    Outcome outcome;
    Alarm* alarm = find(id);
    if (!alarm) return {{}, fmt::format("no alarm \"{}\"", id), true};
    if (!alarm->shelved_until) {
        outcome.refusal = fmt::format("alarm \"{}\" is not shelved", id);
        return outcome;
    }
    alarm->shelved_until.reset();
    alarm->acknowledged = !alarm->active;
    record(*alarm, now, outcome.transitions, user, comment);
    return outcome;
}

AlarmEngine::Outcome AlarmEngine::remove_from_service(std::string_view id, std::string_view user, std::string_view comment,
                                                      Time now) {
    Outcome outcome;
    Alarm* alarm = find(id);
    if (!alarm) return {{}, fmt::format("no alarm \"{}\"", id), true};
    if (alarm->out_of_service) {
        outcome.refusal = fmt::format("alarm \"{}\" is out-of-service already", id);
        return outcome;
    }
    alarm->out_of_service = true;
    alarm->shelved_until.reset();
    record(*alarm, now, outcome.transitions, user, comment);
    return outcome;
}

AlarmEngine::Outcome AlarmEngine::return_to_service(std::string_view id, std::string_view user, std::string_view comment,
                                                    Time now) {
    Outcome outcome;
    Alarm* alarm = find(id);
    if (!alarm) return {{}, fmt::format("no alarm \"{}\"", id), true};
    if (!alarm->out_of_service) {
        outcome.refusal = fmt::format("alarm \"{}\" is in service", id);
        return outcome;
    }
    alarm->out_of_service = false;
    alarm->acknowledged = !alarm->active;
    record(*alarm, now, outcome.transitions, user, comment);
    return outcome;
}

std::vector<AlarmView> AlarmEngine::views() const {
    std::vector<AlarmView> out;
    out.reserve(alarms_.size());
    for (const Alarm& alarm : alarms_) {
        out.push_back({alarm.id, alarm.device, alarm.name, alarm.parameter, alarm.kind, alarm.state, alarm.since,
                       alarm.pv ? alarm.pv : alarm.value, alarm.unit, alarm.severity, alarm.message, alarm.shelved_until});
    }
    return out;
}

}  // namespace loopwire::gateway::alarms
