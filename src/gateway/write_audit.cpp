#include "gateway/write_audit.hpp"

#include <fmt/format.h>

#include "common/peer_text.hpp"
#include "gateway/history_store.hpp"

namespace loopwire::gateway {
namespace {

std::uint16_t word_at(ByteView pdu, std::size_t at) {
    return static_cast<std::uint16_t>((pdu[at] << 8) | pdu[at + 1]);
}

std::string words_from(ByteView pdu, std::size_t at, std::size_t count) {
    std::string out;
    for (std::size_t i = 0; i < count && at + 2 * i + 1 < pdu.size(); ++i) {
        if (!out.empty()) out += ' ';
        out += std::to_string(word_at(pdu, at + 2 * i));
    }
    return out;
}

// Modbus application protocol V1.1b3, 6.11: the coils packed eight to a byte, lowest first.
std::string bits_from(ByteView pdu, std::size_t at, std::size_t count) {
    std::string out;
    for (std::size_t i = 0; i < count && at + i / 8 < pdu.size(); ++i) {
        if (!out.empty()) out += ' ';
        out += ((pdu[at + i / 8] >> (i % 8)) & 1) != 0 ? '1' : '0';
    }
    return out;
}

}  // namespace

std::string audit_refused(std::string_view reason) { return fmt::format("refused: {}", reason); }

std::string audit_line(const AuditRecord& record) {
    const std::string who = record.origin.peer.empty() ? record.origin.front
                                                      : fmt::format("{} {}", record.origin.front, record.origin.peer);
    const std::string user = record.origin.user.empty() ? std::string() : fmt::format(" ({})", record.origin.user);
    // A raw Modbus write names registers, not a parameter, and has no old value.
    if (record.parameter.starts_with("function ")) {
        return without_control_bytes(fmt::format("audit: {}{}: {} {} values {}: {}", who, user, record.device, record.parameter,
                                                 record.new_value, record.outcome));
    }
    // A peer's bytes (an MQTT payload, a parameter's name) never break the log's lines.
    return without_control_bytes(fmt::format("audit: {}{}: {}.{} {} → {}: {}", who, user, record.device, record.parameter,
                                             record.old_value.empty() ? "?" : record.old_value, record.new_value,
                                             record.outcome));
}

// Modbus application protocol V1.1b3, 6.5, 6.6, 6.11, 6.12, 6.16 and 6.17: where each write
// request keeps its address, count and values.
RawWriteText describe_raw_write(ByteView pdu) {
    if (pdu.empty()) return {"an empty request", ""};
    const unsigned function = pdu[0];
    const auto head = [&](std::uint16_t address, std::size_t count) {
        return fmt::format("function {} address {} count {}", function, address, count);
    };
    switch (function) {
        case 5:
            if (pdu.size() >= 5) return {head(word_at(pdu, 1), 1), word_at(pdu, 3) == 0xFF00 ? "1" : "0"};
            break;
        case 6:
            if (pdu.size() >= 5) return {head(word_at(pdu, 1), 1), std::to_string(word_at(pdu, 3))};
            break;
        case 15:
            if (pdu.size() >= 6) return {head(word_at(pdu, 1), word_at(pdu, 3)), bits_from(pdu, 6, word_at(pdu, 3))};
            break;
        case 16:
            if (pdu.size() >= 6) return {head(word_at(pdu, 1), word_at(pdu, 3)), words_from(pdu, 6, word_at(pdu, 3))};
            break;
        case 22:
            if (pdu.size() >= 7) {
                return {head(word_at(pdu, 1), 1), fmt::format("and {:04X}h or {:04X}h", word_at(pdu, 3), word_at(pdu, 5))};
            }
            break;
        case 23:
            if (pdu.size() >= 10) return {head(word_at(pdu, 5), word_at(pdu, 7)), words_from(pdu, 10, word_at(pdu, 7))};
            break;
        default: break;
    }
    return {fmt::format("function {}", function), to_hex(pdu.subspan(1))};
}

std::string raw_reply_outcome(ByteView reply_pdu) {
    if (reply_pdu.size() >= 2 && (reply_pdu[0] & 0x80) != 0) return audit_refused(fmt::format("exception {:02X}h", reply_pdu[1]));
    if (reply_pdu.empty()) return audit_refused("no reply");
    return std::string(audit_confirmed);
}

WriteAudit::WriteAudit(Log log, Clock clock) : log_(std::move(log)), clock_(std::move(clock)) {
    if (!clock_) clock_ = [] { return std::chrono::system_clock::now(); };
}

void WriteAudit::attach(HistoryStore* store) {
    std::lock_guard lock(store_mutex_);
    store_ = store;
}

void WriteAudit::record(AuditRecord record) const {
    if (record.time == std::chrono::system_clock::time_point{}) record.time = clock_();
    if (log_) log_(audit_line(record));
    std::lock_guard lock(store_mutex_);
    if (store_) store_->record_write(record);
}

}  // namespace loopwire::gateway
