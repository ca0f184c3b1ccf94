#pragma once
// The Modbus TCP front's optional read cache (`[modbus_tcp] max_age`): one per device. A read
// request identical to one the line answered within max_age is answered with that reply, so
// many clients polling the same registers cost the line one request per max_age, not one each.
//
// Only reads of coils, discrete inputs, holding and input registers (function codes 1-4,
// Modbus application protocol V1.1b3, 6.1-6.4) are kept: their replies depend on nothing but
// the request and the device's data. The other reading functions are not: 7, 11 and 12 report
// counters and a log that change with every request, 17, 20, 24 and 43 are rare enough not to
// matter. Exception replies are never kept (the next try may succeed), nor are failures.
//
// A write invalidates: forget() drops every reply and moves to a new generation, and a reply
// to a request asked in an older generation is not kept, since the device may have read it
// before the write took effect. Thread-safe: the front asks, the line's thread stores.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>

#include "common/bytes.hpp"

namespace loopwire::gateway {

class ReadCache {
public:
    static constexpr std::size_t default_capacity = 256;

    // Replies older than `max_age` are not given; at most `capacity` are kept (the oldest go).
    explicit ReadCache(std::chrono::milliseconds max_age, std::size_t capacity = default_capacity);

    // Whether replies to this request may be kept at all (function codes 1-4).
    static bool cacheable(ByteView request_pdu);

    // The reply to an identical request stored at most max_age before `now`, if there is one.
    std::optional<Bytes> find(ByteView request_pdu, Instant now) const;

    // Taken before a request goes to the line and handed back to store() with its reply.
    std::uint64_t generation() const;

    // Keeps `reply_pdu`, received at `now`, as the answer to `request_pdu`; ignored for requests
    // that are not cacheable, exception replies, and requests asked before the last forget().
    void store(ByteView request_pdu, Bytes reply_pdu, Instant now, std::uint64_t asked_in);

    // Drops every reply: something was written to the device.
    void forget();

    std::size_t size() const;

private:
    struct Entry {
        Bytes request;
        Bytes reply;
        Instant stored;
    };

    bool fresh(const Entry& entry, Instant now) const { return now - entry.stored <= max_age_; }
    void drop_stale(Instant now);

    std::chrono::milliseconds max_age_;
    std::size_t capacity_;
    mutable std::mutex mutex_;
    std::deque<Entry> entries_;  // oldest first
    std::uint64_t generation_ = 0;
};

}  // namespace loopwire::gateway
