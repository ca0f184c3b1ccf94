#include "gateway/read_cache.hpp"

#include <algorithm>

namespace loopwire::gateway {
namespace {

bool same_bytes(ByteView a, ByteView b) { return std::equal(a.begin(), a.end(), b.begin(), b.end()); }

// A normal reply repeats the request's function code; an exception reply sets its top bit
// (Modbus application protocol V1.1b3, 7).
bool normal_reply_to(ByteView request_pdu, ByteView reply_pdu) {
    return !reply_pdu.empty() && reply_pdu[0] == request_pdu[0];
}

}  // namespace

ReadCache::ReadCache(std::chrono::milliseconds max_age, std::size_t capacity)
    : max_age_(max_age), capacity_(std::max<std::size_t>(capacity, 1)) {}

bool ReadCache::cacheable(ByteView request_pdu) {
    return !request_pdu.empty() && request_pdu[0] >= 1 && request_pdu[0] <= 4;
}

std::optional<Bytes> ReadCache::find(ByteView request_pdu, Instant now) const {
    if (!cacheable(request_pdu)) return std::nullopt;
    std::lock_guard lock(mutex_);
    auto it = std::find_if(entries_.begin(), entries_.end(),
                           [&](const Entry& entry) { return same_bytes(entry.request, request_pdu); });
    if (it == entries_.end() || !fresh(*it, now)) return std::nullopt;
    return it->reply;
}

std::uint64_t ReadCache::generation() const {
    std::lock_guard lock(mutex_);
    return generation_;
}

void ReadCache::store(ByteView request_pdu, Bytes reply_pdu, Instant now, std::uint64_t asked_in) {
    if (!cacheable(request_pdu) || !normal_reply_to(request_pdu, reply_pdu)) return;
    std::lock_guard lock(mutex_);
    if (asked_in != generation_) return;
    std::erase_if(entries_, [&](const Entry& entry) { return same_bytes(entry.request, request_pdu); });
    drop_stale(now);
    if (entries_.size() == capacity_) entries_.pop_front();
    entries_.push_back({Bytes(request_pdu.begin(), request_pdu.end()), std::move(reply_pdu), now});
}

void ReadCache::forget() {
    std::lock_guard lock(mutex_);
    entries_.clear();
    ++generation_;
}

std::size_t ReadCache::size() const {
    std::lock_guard lock(mutex_);
    return entries_.size();
}

// Entries are in the order they were stored, so the stale ones are at the front.
void ReadCache::drop_stale(Instant now) {
    while (!entries_.empty() && !fresh(entries_.front(), now)) entries_.pop_front();
}

}  // namespace loopwire::gateway
