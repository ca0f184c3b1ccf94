#include "gateway/forwarding_unit.hpp"

#include <array>
#include <algorithm>
#include <future>

#include <fmt/format.h>

namespace loopwire::gateway {
namespace {

constexpr std::uint8_t exception_flag = 0x80;
constexpr std::uint8_t illegal_function = 0x01;
constexpr std::uint8_t gateway_path_unavailable = 0x0A;
constexpr std::uint8_t target_failed_to_respond = 0x0B;

// Modbus application protocol V1.1b3, 6: read coils, discrete inputs, holding and input
// registers (1-4), read exception status (7), get comm event counter and log (11, 12), report
// server id (17), read file record (20), read FIFO queue (24), encapsulated interface /
// device identification (43). Everything else may change the device, user-defined codes
// included (nobody can tell what they do), so a read-only gateway refuses it.
constexpr std::array<std::uint8_t, 11> reading_functions{1, 2, 3, 4, 7, 11, 12, 17, 20, 24, 43};

Bytes exception_reply(std::uint8_t function, std::uint8_t code) {
    return Bytes{static_cast<std::uint8_t>(function | exception_flag), code};
}

// What the end of a request on the line does to the unit's read cache, before the client has
// the reply: a read's reply is kept; a write, answered or not, empties the cache, since the
// device may have taken it, and a client reading after its write must see the new value.
struct CacheUpdate {
    std::shared_ptr<ReadCache> cache;  // null: no cache
    std::shared_ptr<Clock> clock;
    Bytes request;  // a cacheable read's PDU, else empty
    std::uint64_t generation = 0;
    bool write = false;

    void operator()(const Result<Bytes>& answered) const {
        if (!cache) return;
        if (write) return cache->forget();
        if (!request.empty() && answered) cache->store(request, *answered, clock->now(), generation);
    }
};

}  // namespace

bool only_reads(std::uint8_t function) {
    return std::find(reading_functions.begin(), reading_functions.end(), function) != reading_functions.end();
}

Bytes failure_reply(std::uint8_t function, const Error& why) {
    switch (why.kind) {
        case ErrorKind::usage: return exception_reply(function, illegal_function);
        // The line is down or failed under the request: the gateway had no path to the device,
        // and the device was never asked, so 0Bh ("no response was obtained from the target
        // device") would blame a device that may be fine and send people to it rather than to
        // the cable or the adapter.
        case ErrorKind::link: return exception_reply(function, gateway_path_unavailable);
        case ErrorKind::exception:
            // The gateway's own refusal with a code (06h for a full queue), 1..127, checked.
            if (why.code > 0 && why.code < exception_flag) {
                return exception_reply(function, static_cast<std::uint8_t>(why.code));
            }
            return exception_reply(function, target_failed_to_respond);
        default: return exception_reply(function, target_failed_to_respond);
    }
}

ForwardingUnit::ForwardingUnit(std::shared_ptr<LineScheduler> line, ForwardingSettings settings,
                               std::shared_ptr<Clock> clock, GatewayLog log)
    : line_(std::move(line)), settings_(settings), clock_(std::move(clock)), log_(std::move(log)) {
    if (settings_.max_age > std::chrono::milliseconds::zero()) {
        cache_ = std::make_shared<ReadCache>(settings_.max_age, settings_.cache_entries);
    }
}

std::optional<Bytes> ForwardingUnit::silent_refusal(ByteView request_pdu, std::string& reason) const {
    if (!settings_.write_refusal || only_reads(request_pdu[0])) return std::nullopt;
    auto refused = settings_.write_refusal();
    if (!refused) return std::nullopt;
    reason = refused->message;
    if (log_) log_(fmt::format("refused function {} to unit {}: {}", request_pdu[0], settings_.line_unit, reason));
    return failure_reply(request_pdu[0], *refused);
}

// Exception 01h for a write the front does not take: from every client (`writes = false`), or
// from this client's address (outside `write_allow`).
std::optional<Bytes> ForwardingUnit::refusal(ByteView request_pdu, const Asker& asker, std::string& reason) const {
    if ((settings_.writes_allowed && asker.may_write) || only_reads(request_pdu[0])) return std::nullopt;
    reason = settings_.writes_allowed ? "the client's address is not in modbus_tcp.write_allow"
                                      : "this gateway is read-only (modbus_tcp.writes = false)";
    if (log_) log_(fmt::format("refused function {} to unit {}: {}", request_pdu[0], settings_.line_unit, reason));
    return exception_reply(request_pdu[0], illegal_function);
}

// A write's record, its outcome still to come; none for a read, and for a broadcast at every
// unit but the one that carries it (a broadcast is one write, recorded once).
std::optional<AuditRecord> ForwardingUnit::audit_record(ByteView request_pdu, bool broadcast, const Asker& asker) const {
    if (!settings_.audit || only_reads(request_pdu[0]) || (broadcast && !settings_.carries_broadcasts)) return std::nullopt;
    AuditRecord record;
    record.origin.front = "modbus_tcp";
    if (asker.peer) record.origin.peer = *asker.peer;
    record.device = broadcast ? std::string("broadcast (unit 0)")
                              : (settings_.device.empty() ? fmt::format("unit {}", settings_.line_unit) : settings_.device);
    auto described = describe_raw_write(request_pdu);
    record.parameter = std::move(described.what);
    record.new_value = std::move(described.values);
    return record;
}

void ForwardingUnit::audit(std::optional<AuditRecord>& record, std::string outcome) const {
    if (!record) return;
    record->outcome = std::move(outcome);
    settings_.audit->record(std::move(*record));
    record.reset();
}

std::optional<Bytes> ForwardingUnit::cached(ByteView request_pdu, bool broadcast) const {
    if (!cache_ || broadcast) return std::nullopt;
    return cache_->find(request_pdu, clock_->now());
}

LineRequest ForwardingUnit::line_request(Bytes request_pdu, bool broadcast, const Asker& asker, ReplyCallback reply,
                                         std::optional<AuditRecord> audited) const {
    const std::uint8_t function = request_pdu[0];
    const bool write = !only_reads(function);
    CacheUpdate update{cache_, clock_, {}, 0, write};
    if (cache_ && !broadcast && ReadCache::cacheable(request_pdu)) {
        update.request = request_pdu;
        update.generation = cache_->generation();
    }
    LineRequest request;
    request.unit = broadcast ? std::uint8_t{0} : settings_.line_unit;
    request.priority = write ? Priority::write : Priority::client;
    request.pdu = std::move(request_pdu);
    request.client = asker.origin;
    request.still_wanted = asker.still_wanted;
    request.deadline = clock_->now() + settings_.queue_limit;
    std::function<void()> on_written = write ? settings_.on_write_answered : nullptr;
    request.done = [function, broadcast, update = std::move(update), on_written = std::move(on_written),
                    reply = std::move(reply), audited = std::move(audited), audit = settings_.audit](Result<Bytes> answered) mutable {
        update(answered);
        if (audited) {
            if (!answered) {
                audited->outcome = audit_refused(answered.error().message);
            } else if (broadcast) {
                audited->outcome = "sent: a broadcast is not answered";
            } else {
                audited->outcome = raw_reply_outcome(*answered);
            }
            audit->record(std::move(*audited));
        }
        // A normal reply: the function code echoed, not function + 80h. A broadcast has none.
        if (on_written && answered && !answered->empty() && ((*answered)[0] & 0x80) == 0) on_written();
        if (broadcast) return reply(std::nullopt);  // nobody answers a broadcast (2.1 of the serial spec)
        reply(answered ? std::move(*answered) : failure_reply(function, answered.error()));
    };
    return request;
}

void ForwardingUnit::handle_async(Bytes request_pdu, bool broadcast, const Asker& asker, ReplyCallback reply) {
    if (request_pdu.empty()) return reply(std::nullopt);
    auto audited = audit_record(request_pdu, broadcast, asker);
    std::string reason;
    if (auto refused = refusal(request_pdu, asker, reason)) {
        audit(audited, audit_refused(reason));
        return reply(broadcast ? std::nullopt : std::move(refused));
    }
    // A broadcast is every device's: one silent device does not hold it back.
    if (!broadcast) {
        if (auto refused = silent_refusal(request_pdu, reason)) {
            audit(audited, audit_refused(reason));
            return reply(std::move(refused));
        }
    }
    // What was kept may be out of date once a write is taken. A broadcast write reaches this
    // device too, even when another unit carries it to the line.
    if (cache_ && !only_reads(request_pdu[0])) cache_->forget();
    if (broadcast && !settings_.carries_broadcasts) return reply(std::nullopt);
    if (auto kept = cached(request_pdu, broadcast)) return reply(std::move(kept));
    line_->submit(line_request(std::move(request_pdu), broadcast, asker, std::move(reply), std::move(audited)));
}

std::optional<Bytes> ForwardingUnit::handle(ByteView request_pdu, bool broadcast) {
    std::promise<std::optional<Bytes>> answered;
    auto future = answered.get_future();
    handle_async(Bytes(request_pdu.begin(), request_pdu.end()), broadcast, 0,
                 [&answered](std::optional<Bytes> reply) { answered.set_value(std::move(reply)); });
    return future.get();
}

}  // namespace loopwire::gateway
