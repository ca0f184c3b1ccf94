#include "client/monitor_state.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "client/identity_check.hpp"
#include "common/never_sent.hpp"

namespace loopwire::device {

WatchedDevice watch(std::string label, const std::vector<const device::Parameter*>& parameters,
                    const device::Profile* identify_as) {
    WatchedDevice device;
    device.label = std::move(label);
    for (const auto* parameter : parameters) device.values.push_back(WatchedValue{parameter, {}, {}, false, false, "not read yet"});
    if (identify_as && !identification_words(*identify_as).empty()) device.identified_as = identify_as;
    return device;
}

std::vector<const device::Parameter*> identity_words_due(const WatchedDevice& device) {
    if (!device.identified_as || device.identity_confirmed) return {};
    return identification_words(*device.identified_as);
}

std::vector<const device::Parameter*> with_identity_words(std::vector<const device::Parameter*> parameters,
                                                          const WatchedDevice& device) {
    for (const auto* word : identity_words_due(device)) {
        if (std::find(parameters.begin(), parameters.end(), word) == parameters.end()) parameters.push_back(word);
    }
    return parameters;
}

namespace {

const device::ParameterReading* find_reading(const device::ReadReport& report, const device::Parameter* parameter) {
    for (const auto& reading : report.readings) {
        if (reading.parameter == parameter) return &reading;
    }
    return nullptr;
}

void record_value(WatchedValue& value, const device::ParameterReading* reading, MonitorClock::time_point now) {
    if (!reading || !reading->value) {
        value.fresh = false;
        value.changed = false;
        value.error = reading ? reading->error : "not read";
        return;
    }
    value.changed = value.last && value.last->raw != reading->value->raw;
    value.last = reading->value;
    value.read_at = now;
    value.fresh = true;
    value.error.clear();
}

// A poll that read nothing: every value keeps its last reading, none is fresh.
void record_failed_poll(WatchedDevice& device, DeviceStatus status, const std::string& failure) {
    ++device.polls;
    ++device.errors;
    device.status = status;
    device.last_error = failure;
    for (auto& value : device.values) {
        value.fresh = false;
        value.changed = false;
        value.error = failure;
    }
}

// Exception 0Ah (gateway path unavailable) or 0Bh (gateway target device failed to respond).
bool gateway_found_no_device(const std::optional<Error>& error) {
    return error && error->kind == ErrorKind::exception && (error->code == 0x0A || error->code == 0x0B);
}

// Whether the poll is of the device named; false when it answered as another (recorded here).
bool identity_holds(WatchedDevice& device, const device::ReadReport& report) {
    if (!device.identified_as || device.identity_confirmed) return true;
    const auto verdict = judge_identity(*device.identified_as, report);
    if (verdict.kind == IdentityVerdict::Kind::holds) device.identity_confirmed = true;
    if (verdict.kind != IdentityVerdict::Kind::wrong) return true;
    record_failed_poll(device, DeviceStatus::wrong_device,
                       fmt::format("the unit is not {}: {}", device.label, verdict.reason));
    return false;
}

}  // namespace

void record_line_down(WatchedDevice& device, const std::string& failure) {
    device.identity_confirmed = false;  // whatever answers when the line is back is checked again
    record_failed_poll(device, DeviceStatus::line_down, failure);
}

void record_outcome(WatchedDevice& device, const device::ReadReport& report, const std::optional<Error>& stopped_by,
                    MonitorClock::time_point now) {
    device.next_try.reset();
    if (!stopped_by) {
        if (gateway_found_no_device(report.first_error)) return record_poll(device, report, false, report.first_error->message, now);
        if (!identity_holds(device, report)) return;
        return record_poll(device, report, true, {}, now);
    }
    // Blocks read before it are dropped too: a device half read this time is not a device that
    // answered part of its parameters (`partial`).
    if (says_nothing_of_the_device(*stopped_by)) return record_unsent(device, stopped_by->message);
    if (stopped_by->kind == ErrorKind::link) return record_line_down(device, stopped_by->message);
    record_poll(device, report, false, stopped_by->message, now);
}

void record_poll(WatchedDevice& device, const device::ReadReport& report, bool answered, const std::string& failure,
                 MonitorClock::time_point now) {
    if (!answered) {
        device.identity_confirmed = false;  // whatever answers after the silence is checked again
        return record_failed_poll(device, DeviceStatus::no_reply, failure);
    }
    ++device.polls;
    for (const auto& [name, raw] : report.raw) device.known.insert_or_assign(name, raw);
    bool all_read = true;
    for (auto& value : device.values) {
        record_value(value, find_reading(report, value.parameter), now);
        all_read = all_read && value.fresh;
    }
    if (!all_read) {
        ++device.errors;
        device.last_error = report.first_error ? report.first_error->message : "a value could not be decoded";
    }
    device.status = all_read ? DeviceStatus::ok : DeviceStatus::partial;
}

void record_skipped(WatchedDevice& device) {
    device.status = DeviceStatus::waiting;
    for (auto& value : device.values) {
        value.fresh = false;
        value.changed = false;
        value.error = "waiting to retry: " + device.last_error;
    }
}

void record_unsent(WatchedDevice& device, const std::string& why) {
    device.status = DeviceStatus::waiting;
    device.last_error = why;  // not counted in `errors`: nothing failed at the device
    for (auto& value : device.values) {
        value.fresh = false;
        value.changed = false;
        value.error = "not polled this time: " + why;
    }
}

std::optional<double> age_seconds(const WatchedValue& value, MonitorClock::time_point now) {
    if (!value.read_at) return std::nullopt;
    return std::chrono::duration<double>(now - *value.read_at).count();
}

std::string value_status(const WatchedDevice& device, const WatchedValue& value) {
    if (value.fresh) return value.last->status;
    // A device that answered did not give this value; otherwise the device's status says why.
    if (answered(device.status)) return std::string(failed_value_status);
    // What answered is not the configured device: none of its values is this device's.
    if (device.status == DeviceStatus::wrong_device) return std::string(failed_value_status);
    return std::string(status_text(device.status));
}

}  // namespace loopwire::device
