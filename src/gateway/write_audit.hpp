#pragma once
// The audit of writes: every write from every front (the HTTP API and its dashboard, MQTT,
// Sparkplug, the Modbus TCP front) leaves one record of when, who, what and how it ended, as
// a line on the gateway's log and, with [history], a row of the history file's `writes` table
// (gateway/history_store.hpp), read back by GET /api/audit and `loopwire audit`.
//
// Threads: record() may be called from any thread (a front's, a line's, the engine's loop); it
// formats one log line and queues the row for the store's writer, never waiting for SQLite.
#include <chrono>
#include <cstddef>
#include <functional>
#include <mutex>
#include <optional>
#include <string>

#include "common/bytes.hpp"

namespace loopwire::gateway {

class HistoryStore;

// Who asked for a write: the front ("http", "mqtt", "sparkplug", "modbus_tcp"; "reload" for a
// reload of the configuration, gateway/config_change.hpp), the peer as
// the front knows it (the HTTP or Modbus TCP client's address, the broker's client id or
// "broker"), and the user (empty until the fronts know users).
struct WriteOrigin {
    std::string front;
    std::string peer;
    std::string user;
};

// One write as the audit keeps it. `parameter` is the profile's name for a write by name, or
// what a raw Modbus request wrote ("function 16 address 100 count 2"); `old_value` and
// `new_value` are in engineering units with the unit ("150.0 °C"), `old_value` empty when it is
// not known (a raw write, a value not polled yet). `outcome`: "confirmed" (the device answered),
// or "refused: REASON" (policy, validation, an exception, a timeout, a busy line).
struct AuditRecord {
    std::chrono::system_clock::time_point time;
    WriteOrigin origin;
    std::string device;
    std::string parameter;
    std::string old_value;
    std::string new_value;
    std::string outcome;
};

inline constexpr std::string_view audit_confirmed = "confirmed";
// "refused: REASON".
std::string audit_refused(std::string_view reason);

// The record's log line: "audit: http 127.0.0.1: oven.set_point 150.0 °C → 160.0 °C: confirmed"
// ("? → 160.0 °C" when the old value is unknown; no peer, no space for it); a raw Modbus write:
// "audit: modbus_tcp 127.0.0.1:50312: oven function 6 address 717 count 1 values 1600: confirmed";
// a reload: "audit: reload SIGHUP: configuration plant.toml: device kiln added to line furnace: confirmed".
std::string audit_line(const AuditRecord& record);

// A raw Modbus write request's PDU in words, for the audit: its function, address, count and
// values ("function 6 address 100 count 1", "values 150"; coils as 0 and 1). Functions other
// than 5, 6, 15, 16, 22 and 23 are "function N" with the PDU's bytes in hex as the values.
struct RawWriteText {
    std::string what;    // "function 16 address 100 count 2"
    std::string values;  // "150 20"
};
RawWriteText describe_raw_write(ByteView pdu);

// A Modbus reply's outcome for the audit: "confirmed" for a normal reply, "refused: exception
// 02h" for an exception reply.
std::string raw_reply_outcome(ByteView reply_pdu);

// GET /api/audit's and `loopwire audit`'s question: the records stamped in [from, to], of one
// device (empty: every one), newest first, at most `limit`.
struct AuditQuery {
    std::chrono::system_clock::time_point from;
    std::chrono::system_clock::time_point to;
    std::string device;
    std::size_t limit = 1000;
};
inline constexpr std::size_t max_audit_limit = 100000;

// Where the records go: the log (always), the history store once it is attached.
class WriteAudit {
public:
    using Log = std::function<void(const std::string&)>;
    using Clock = std::function<std::chrono::system_clock::time_point()>;
    explicit WriteAudit(Log log, Clock clock = {});

    // From now on records are also queued for the store; nullptr: no longer (the store is
    // going). The store must outlive its attachment.
    void attach(HistoryStore* store);

    // Stamps the record now (when its time is unset), logs it at notice level (gateway_notice_prefix)
    // and queues its row.
    void record(AuditRecord record) const;

private:
    Log log_;
    Clock clock_;
    mutable std::mutex store_mutex_;
    HistoryStore* store_ = nullptr;
};

}  // namespace loopwire::gateway
