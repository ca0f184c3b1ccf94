#pragma once
// The Modbus TCP front's view of one device: a unit handler that passes each request's PDU, of
// any function code, to the line the device is on and answers with what the device answered
// (Modbus Messaging on TCP/IP Implementation Guide V1.0b, 4.4.2: a gateway's unit id selects
// the device behind it). With a max_age, reads the line answered recently are answered from the
// unit's ReadCache instead (gateway/read_cache.hpp).
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "common/clock.hpp"
#include "common/result.hpp"
#include "gateway/line_scheduler.hpp"
#include "gateway/read_cache.hpp"
#include "gateway/write_audit.hpp"
#include "session/unit_handler.hpp"

namespace loopwire::gateway {

struct ForwardingSettings {
    std::uint8_t line_unit = 1;      // the device's unit id on its line
    bool writes_allowed = true;      // false: anything but a read is refused with exception 1
    bool carries_broadcasts = false; // one unit per line passes unit-0 requests on, once
    // A request not on the wire within this is answered 0Bh instead: the client has long given
    // up on it (Modbus TCP clients wait 1-3 s), and sending it would only delay the others.
    std::chrono::milliseconds queue_limit{3000};
    // Reads of function codes 1-4 answered from the line's reply to the same request up to this
    // old; 0: every request goes to the line.
    std::chrono::milliseconds max_age{0};
    std::size_t cache_entries = ReadCache::default_capacity;
    // Told, on the line's thread, of every write a client made through this unit that the device
    // answered with a normal reply: a word that bounds a polled value may have moved.
    std::function<void()> on_write_answered = {};
    // Why a write (any function that is not a read) cannot go to the device now, or none: the
    // gateway's write policy (gateway/device_writer.hpp, silent_device_refusal). A refused
    // write is answered with failure_reply at once and never reaches the line; reads and
    // broadcasts still go.
    std::function<std::optional<Error>()> write_refusal = {};
    // Every write a client asks for (any function that is not a read) is audited here, once:
    // refused, answered or failed. None: not audited. Must outlive the unit.
    std::shared_ptr<const WriteAudit> audit = {};
    std::string device = {};  // the device's configured name, for the audit
};

// What the gateway says of refused or failed requests (for its log). A line that begins with
// "warning: " is one a person must see (a line down, a device gone silent or answering as
// another, polls falling behind): the log gives it the warning level, without the prefix. One
// that begins with "notice: " says such a state has ended (the line up again, the device
// answering again): the notice level, between warning and info (app/gateway_log.hpp).
using GatewayLog = std::function<void(const std::string&)>;
inline constexpr std::string_view gateway_warning_prefix = "warning: ";
inline constexpr std::string_view gateway_notice_prefix = "notice: ";

class ForwardingUnit final : public session::UnitHandler {
public:
    ForwardingUnit(std::shared_ptr<LineScheduler> line, ForwardingSettings settings, std::shared_ptr<Clock> clock,
                   GatewayLog log = {});

    // For a front that cannot wait (a serial slave session): blocks until the line answered.
    std::optional<Bytes> handle(ByteView request_pdu, bool broadcast) override;
    // The request is dropped unsent, and counted abandoned, if the asker stops wanting it while
    // it waits for the line (a closed connection).
    void handle_async(Bytes request_pdu, bool broadcast, const Asker& asker, ReplyCallback reply) override;

private:
    std::optional<Bytes> refusal(ByteView request_pdu, const Asker& asker, std::string& reason) const;
    std::optional<Bytes> silent_refusal(ByteView request_pdu, std::string& reason) const;
    std::optional<AuditRecord> audit_record(ByteView request_pdu, bool broadcast, const Asker& asker) const;
    void audit(std::optional<AuditRecord>& record, std::string outcome) const;
    std::optional<Bytes> cached(ByteView request_pdu, bool broadcast) const;
    LineRequest line_request(Bytes request_pdu, bool broadcast, const Asker& asker, ReplyCallback reply,
                             std::optional<AuditRecord> audited) const;

    std::shared_ptr<LineScheduler> line_;
    ForwardingSettings settings_;
    std::shared_ptr<Clock> clock_;
    GatewayLog log_;
    // Shared with the completions of requests on the line, which may end after the unit has gone.
    std::shared_ptr<ReadCache> cache_;  // null without a max_age
};

// Modbus application protocol V1.1b3, 7: the reply a gateway gives for a request it could not
// get answered. 0Bh (target device failed to respond) for silence and bad replies; 0Ah (gateway
// path unavailable) when the line is down or failed, so the request never reached the device;
// 01h for a request the line's framing cannot carry (Linking); the gateway's own refusal's code
// when the line refused it with one (06h, server device busy, for a full queue: line_scheduler.hpp).
Bytes failure_reply(std::uint8_t function, const Error& why);

// Function codes that only read: what a gateway with `writes = false` still passes on.
bool only_reads(std::uint8_t function);

}  // namespace loopwire::gateway
