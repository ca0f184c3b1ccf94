#include "gateway/write_audit.hpp"

#include <fmt/format.h>

#include "common/peer_text.hpp"
#include "gateway/forwarding_unit.hpp"  // the GatewayLog level prefixes
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

// The length of the well-formed UTF-8 sequence at `at` (RFC 3629, 4: no overlong forms, no
// surrogates, nothing past U+10FFFF), or 0.
std::size_t utf8_sequence(std::string_view text, std::size_t at) {
    const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
    const unsigned char lead = byte(at);
    std::size_t length = 0;
    unsigned char low = 0x80;
    unsigned char high = 0xBF;
    if (lead >= 0xC2 && lead <= 0xDF) {
        length = 2;
    } else if (lead >= 0xE0 && lead <= 0xEF) {
        length = 3;
        if (lead == 0xE0) low = 0xA0;
        if (lead == 0xED) high = 0x9F;
    } else if (lead >= 0xF0 && lead <= 0xF4) {
        length = 4;
        if (lead == 0xF0) low = 0x90;
        if (lead == 0xF4) high = 0x8F;
    } else {
        return 0;
    }
    if (at + length > text.size()) return 0;
    if (byte(at + 1) < low || byte(at + 1) > high) return 0;
    for (std::size_t i = 2; i < length; ++i) {
        if (byte(at + i) < 0x80 || byte(at + i) > 0xBF) return 0;
    }
    return length;
}

// A field a peer may have given (an MQTT topic's or payload's bytes, an HTTP body's names), for
// the log: control bytes and bytes that are not UTF-8 as \xNN, text in any script as it is,
// and cut after `limit` bytes (a refusal's reason is the gateway's own words, kept whole).
std::string shown(std::string_view text, std::size_t limit = 4 * peer_text_excerpt) {
    std::string out;
    std::size_t at = 0;
    while (at < text.size() && at < limit) {
        const auto byte = static_cast<unsigned char>(text[at]);
        if (byte >= 0x20 && byte < 0x7F) {
            out += text[at++];
        } else if (const std::size_t length = byte >= 0x80 ? utf8_sequence(text, at) : 0; length > 0) {
            out.append(text.substr(at, length));
            at += length;
        } else {
            out += fmt::format("\\x{:02x}", byte);
            ++at;
        }
    }
    if (at < text.size()) out += fmt::format("… ({} bytes)", text.size());
    return out;
}

}  // namespace

std::string audit_refused(std::string_view reason) { return fmt::format("refused: {}", reason); }

std::string audit_line(const AuditRecord& record) {
    const std::string who = record.origin.peer.empty() ? record.origin.front
                                                      : fmt::format("{} {}", record.origin.front, shown(record.origin.peer));
    const std::string user = record.origin.user.empty() ? std::string() : fmt::format(" ({})", shown(record.origin.user));
    // A reload names the configuration and what it changed (gateway/config_change.hpp).
    if (record.origin.front == "reload") {
        return fmt::format("audit: {}{}: {}: {}: {}", who, user, shown(record.parameter),
                           shown(record.new_value, record.new_value.size()),
                           shown(record.outcome, record.outcome.size()));
    }
    // A raw Modbus write names registers, not a parameter, and has no old value.
    if (record.parameter.starts_with("function ")) {
        return fmt::format("audit: {}{}: {} {} values {}: {}", who, user, shown(record.device), record.parameter,
                           shown(record.new_value), shown(record.outcome, record.outcome.size()));
    }
    // A peer's bytes (an MQTT topic or payload, a name in an HTTP body) never break the log's
    // lines nor reach it raw.
    return fmt::format("audit: {}{}: {}.{} {} → {}: {}", who, user, shown(record.device), shown(record.parameter),
                       record.old_value.empty() ? "?" : shown(record.old_value), shown(record.new_value),
                       shown(record.outcome, record.outcome.size()));
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
    // At notice level: a write changes a device, which `journalctl -p notice` should show
    // without the info lines of every poll.
    if (log_) log_(fmt::format("{}{}", gateway_notice_prefix, audit_line(record)));
    std::lock_guard lock(store_mutex_);
    if (store_) store_->record_write(record);
}

}  // namespace loopwire::gateway
