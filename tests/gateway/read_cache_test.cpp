// The read cache of the Modbus TCP front (gateway/read_cache.hpp): what it keeps, for how long,
// how many, and what empties it.
#include <gtest/gtest.h>

#include "gateway/read_cache.hpp"
#include "support/test_bytes.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using loopwire::testing::hex;

const Instant start = Instant{} + 1h;

// A read of one holding register, numbered `address`, and its reply.
Bytes read_of(int address) { return Bytes{0x03, 0x00, static_cast<std::uint8_t>(address), 0x00, 0x01}; }
Bytes reply_of(int value) { return Bytes{0x03, 0x02, 0x00, static_cast<std::uint8_t>(value)}; }

TEST(ReadCache, AReplyIsGivenForTheSameRequestUpToMaxAge) {
    ReadCache cache(500ms);
    cache.store(read_of(1), reply_of(42), start, cache.generation());
    ASSERT_TRUE(cache.find(read_of(1), start).has_value());
    EXPECT_EQ(to_hex(*cache.find(read_of(1), start + 500ms)), "03 02 00 2A");
    EXPECT_FALSE(cache.find(read_of(1), start + 501ms).has_value());
}

TEST(ReadCache, ADifferentRequestMisses) {
    ReadCache cache(500ms);
    cache.store(read_of(1), reply_of(42), start, cache.generation());
    EXPECT_FALSE(cache.find(read_of(2), start).has_value());
    EXPECT_FALSE(cache.find(hex("03 00 01 00 02"), start).has_value()) << "another quantity is another request";
    EXPECT_FALSE(cache.find(hex("04 00 01 00 01"), start).has_value()) << "input registers are not holding registers";
}

TEST(ReadCache, OnlyReadsOfCoilsInputsAndRegistersAreKept) {
    for (int function : {1, 2, 3, 4}) {
        EXPECT_TRUE(ReadCache::cacheable(Bytes{static_cast<std::uint8_t>(function), 0, 0, 0, 1})) << function;
    }
    for (int function : {5, 6, 7, 11, 12, 15, 16, 17, 20, 23, 24, 43}) {
        EXPECT_FALSE(ReadCache::cacheable(Bytes{static_cast<std::uint8_t>(function), 0, 0, 0, 1})) << function;
    }
    ReadCache cache(500ms);
    cache.store(hex("07"), hex("07 00"), start, cache.generation());
    cache.store(hex("06 00 01 00 05"), hex("06 00 01 00 05"), start, cache.generation());
    EXPECT_EQ(cache.size(), 0u);
    EXPECT_FALSE(cache.find(hex("07"), start).has_value());
}

TEST(ReadCache, ExceptionRepliesAreNotKept) {
    ReadCache cache(500ms);
    cache.store(read_of(1), hex("83 02"), start, cache.generation());
    cache.store(read_of(2), Bytes{}, start, cache.generation());
    EXPECT_EQ(cache.size(), 0u);
    EXPECT_FALSE(cache.find(read_of(1), start).has_value());
}

TEST(ReadCache, ForgetDropsEverythingAndRefusesRepliesAskedBefore) {
    ReadCache cache(500ms);
    const auto before = cache.generation();
    cache.store(read_of(1), reply_of(1), start, before);
    cache.forget();
    EXPECT_FALSE(cache.find(read_of(1), start).has_value());
    // A read that went out before the write may carry the value from before it.
    cache.store(read_of(2), reply_of(2), start, before);
    EXPECT_FALSE(cache.find(read_of(2), start).has_value());
    cache.store(read_of(2), reply_of(3), start, cache.generation());
    EXPECT_EQ(to_hex(*cache.find(read_of(2), start)), "03 02 00 03");
}

TEST(ReadCache, ANewerReplyReplacesTheOlder) {
    ReadCache cache(500ms);
    cache.store(read_of(1), reply_of(1), start, cache.generation());
    cache.store(read_of(1), reply_of(2), start + 400ms, cache.generation());
    EXPECT_EQ(cache.size(), 1u);
    EXPECT_EQ(to_hex(*cache.find(read_of(1), start + 800ms)), "03 02 00 02");
}

TEST(ReadCache, TheBoundHoldsByDroppingTheOldest) {
    ReadCache cache(1h, 4);
    for (int address = 0; address < 10; ++address) {
        cache.store(read_of(address), reply_of(address), start + address * 1ms, cache.generation());
        EXPECT_LE(cache.size(), 4u);
    }
    for (int address = 0; address < 10; ++address) {
        EXPECT_EQ(cache.find(read_of(address), start + 10ms).has_value(), address >= 6) << address;
    }
}

TEST(ReadCache, TheDefaultBoundIs256) {
    ReadCache cache(1h);
    for (int address = 0; address < 300; ++address) {
        cache.store(
            Bytes{0x03, static_cast<std::uint8_t>(address >> 8), static_cast<std::uint8_t>(address & 0xFF), 0x00, 0x01},
            reply_of(1), start, cache.generation());
    }
    EXPECT_EQ(cache.size(), ReadCache::default_capacity);
    EXPECT_EQ(ReadCache::default_capacity, 256u);
}

TEST(ReadCache, StaleRepliesLeaveWhenOthersAreStored) {
    ReadCache cache(500ms);
    cache.store(read_of(1), reply_of(1), start, cache.generation());
    cache.store(read_of(2), reply_of(2), start + 100ms, cache.generation());
    cache.store(read_of(3), reply_of(3), start + 550ms, cache.generation());
    EXPECT_EQ(cache.size(), 2u) << "the reply stored at the start is past max_age";
}

}  // namespace
}  // namespace loopwire::gateway
