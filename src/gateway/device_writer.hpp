#pragma once
// Writes by parameter name for the gateway's fronts (MQTT, HTTP): the same checks as the CLI's
// `write` (access, type, decimals, range, the device's mode), then the planned requests, sent
// through the device's line scheduler at Priority::write so they go before the polls.
//
// Threads: none of its own. Each line's writes go one after the other (the line carries one
// request at a time anyway), each started on the gateway's event loop (gateway/engine.hpp) and
// carried by the line's scheduler without blocking. A front hands a write over with
// write_async() and hears the outcome from the completion, so a write waiting for a slow or
// dead line never holds up a write to another line, nor the front's own thread. Each line's
// queue is bounded: beyond `queue_limit` writes waiting, more are refused as busy. Time is the
// loop's clock (gateway/event_loop.hpp): virtual in the soak (tests/gateway/line_soak_test.cpp).
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "client/device_client.hpp"
#include "common/result.hpp"
#include "gateway/event_loop.hpp"
#include "gateway/line_scheduler.hpp"
#include "gateway/value_cache.hpp"
#include "gateway/write_audit.hpp"

namespace loopwire::gateway {

// The write policy every front follows (HTTP, MQTT, Sparkplug, the Modbus TCP front): a write
// to a device its polls find silent (`no-reply`: in back-off until it answers again), whose
// line is down (`line-down`), or that is not the configured device (`wrong-device`) is refused
// at once, unsent, rather than left to wait out the line's timeout. The error's kind says
// which: ErrorKind::timeout (the device is silent: the Modbus TCP front answers 0Bh),
// ErrorKind::link (no path to it: 0Ah), ErrorKind::mismatch (another device answers: 0Bh).
// None for any other status, and before the device's first poll: its write goes.
std::optional<Error> silent_device_refusal(const std::string& device, const std::optional<DeviceSeen>& seen);

// A device the fronts may write to: its configured name, profile and unit, and its line.
struct WritableDevice {
    std::string name;
    device::DeviceAddress address;
    std::shared_ptr<LineScheduler> line;
};

// One value to write: the parameter's name (or mnemonic, or alias) and the text a user gives
// the CLI ("150", "on").
struct WriteAssignment {
    std::string parameter;
    std::string text;
};

// What was written: each parameter's profile name and the text it was given, in order.
struct WrittenValues {
    std::vector<std::pair<std::string, std::string>> values;
};

// The outcome of a write; must not throw, nor block. Runs exactly once, on the thread of the
// line's last reply (or the engine's loop), or at once on the caller's thread when the write is refused before it is queued (an unknown device
// or parameter, no value).
using WriteCompletion = std::function<void(Result<WrittenValues>)>;

// A value as the polls last read it, for the audit's "old value": its text with the decimals
// it is shown with, and its unit. None when the device or parameter has not been read.
struct KnownValue {
    std::string text;
    int decimals = 0;
    std::string unit;
};
using KnownValueLookup = std::function<std::optional<KnownValue>(const std::string& device, const std::string& parameter)>;

class DeviceWriter {
public:
    static constexpr std::size_t default_queue_limit = 256;

    // `write_limit`: how long a write may wait for its line, from the moment it is queued,
    // before it is given up unsent. `queue_limit`: writes that may wait for one line.
    DeviceWriter(EventLoop& loop, std::vector<WritableDevice> devices, std::chrono::milliseconds write_limit,
                 std::size_t queue_limit = default_queue_limit);
    // Fails the writes still queued (ErrorKind::link, "gateway stopping"); each line's write
    // under way finishes and its completion runs first.
    ~DeviceWriter();
    DeviceWriter(const DeviceWriter&) = delete;
    DeviceWriter& operator=(const DeviceWriter&) = delete;

    // The device of that configured name, or nullptr.
    const WritableDevice* find(const std::string& name) const;
    // Every device's configured name, in the configuration's order.
    std::vector<std::string> device_names() const;

    // Validates every assignment, then writes them in planned blocks; nothing is sent when one
    // is invalid. The error says which name or value was wrong, or how the device refused, in
    // words (the profile's meaning of the exception code).
    //
    // Returns false, and `done` never runs, when the device's line already has `queue_limit`
    // writes waiting: the caller answers "busy" in its own words.
    //
    // With an audit (audit()), each assignment leaves one record with `origin`, whatever the
    // outcome: refused before anything is sent, busy, or the device's answer.
    [[nodiscard]] bool write_async(const std::string& device, std::vector<WriteAssignment> assignments,
                                   WriteCompletion done, WriteOrigin origin = {}) const;

    // The same, waiting for the outcome (a busy line is an error here). For callers that may
    // block: never the engine's loop, which the fronts run on.
    Result<WrittenValues> write(const std::string& device, const std::vector<WriteAssignment>& assignments,
                                WriteOrigin origin = {}) const;

    // Writes queued or under way on every line now.
    std::size_t pending() const;

    // From now on every write to a device `lookup` finds silent is refused at once
    // (silent_device_refusal): write_async runs its completion before returning. Set once,
    // before the first write; without it every write goes to its line.
    void refuse_silent(DeviceLookup lookup);

    // Why a write to `device` would be refused now (silent_device_refusal), or none: for a
    // front that answers such a refusal in its own way (an HTTP status) before asking.
    std::optional<Error> refusal(const std::string& device) const;

    // Told of every write that landed (the device's configured name and what was written),
    // on the engine's loop, before its asker: the polls read again the limits it may have
    // moved (PollGroups::written). Set once, before the first write.
    using WrittenHook = std::function<void(const std::string& device, const WrittenValues& written)>;
    void on_written(WrittenHook hook);

    // A front's refusal of a write it never handed over (its own policy, a value it could not
    // read, its own limit of writes waiting, the device's silence it checked first): audited as
    // write_async's refusals are, one record an assignment (one without a parameter when there
    // is none). Nothing without an audit.
    void audit_refusal(const std::string& device, const std::vector<WriteAssignment>& assignments, const WriteOrigin& origin,
                       const std::string& reason) const;

    // Every write is audited from now on, its old value looked up in `known` (the value
    // cache). Set once, before the first write; `audit` must outlive the writer.
    void audit(const WriteAudit* audit, KnownValueLookup known);

private:
    struct Target;
    struct LineWriter;
    EventLoop& loop_;
    std::shared_ptr<WrittenHook> written_hook_ = std::make_shared<WrittenHook>();
    DeviceLookup lookup_;
    const WriteAudit* audit_ = nullptr;
    KnownValueLookup known_;
    std::vector<std::unique_ptr<Target>> targets_;
    std::vector<std::unique_ptr<LineWriter>> lines_;  // one a line scheduler; stopped first
};

}  // namespace loopwire::gateway
