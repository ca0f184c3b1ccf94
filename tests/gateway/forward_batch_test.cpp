// The forwarder's batch (gateway/forward_batch.hpp): the rows in COPY's binary format, and the
// minutes computed as PostgreSQL's own statement computes them (history_forward_test.cpp runs
// both against a real server).
#include "gateway/forward_batch.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace loopwire::gateway {
namespace {

constexpr std::int64_t t0 = 1767225600000;  // 2026-01-01T00:00:00Z, on a minute

// COPY's binary format read back, as the server reads it: each tuple's fields as their bytes,
// none for NULL. Checks the signature, the header and the trailer on the way.
using Field = std::optional<std::string>;
std::vector<std::vector<Field>> tuples_of(const std::string& data) {
    std::size_t at = 0;
    const auto take = [&](std::size_t n) {
        if (at + n > data.size()) throw std::runtime_error("COPY data cut short");
        std::string bytes = data.substr(at, n);
        at += n;
        return bytes;
    };
    const auto number = [&](std::size_t n) {
        std::uint64_t value = 0;
        for (const char c : take(n)) value = (value << 8) | static_cast<unsigned char>(c);
        return value;
    };
    if (take(11) != std::string("PGCOPY\n\xff\r\n\0", 11)) throw std::runtime_error("no COPY signature");
    if (number(4) != 0 || number(4) != 0) throw std::runtime_error("unexpected flags or header extension");
    std::vector<std::vector<Field>> tuples;
    for (;;) {
        const auto fields = static_cast<std::uint16_t>(number(2));
        if (fields == 0xffff) break;
        std::vector<Field> tuple;
        for (std::uint16_t i = 0; i < fields; ++i) {
            const auto length = static_cast<std::int32_t>(static_cast<std::uint32_t>(number(4)));
            tuple.push_back(length < 0 ? Field() : Field(take(static_cast<std::size_t>(length))));
        }
        tuples.push_back(std::move(tuple));
    }
    if (at != data.size()) throw std::runtime_error("bytes after the COPY trailer");
    return tuples;
}

std::string big_endian(std::uint64_t value) {
    std::string bytes(8, '\0');
    for (int i = 7; i >= 0; --i, value >>= 8) bytes[static_cast<std::size_t>(i)] = static_cast<char>(value & 0xff);
    return bytes;
}

TEST(ForwardBatch, RowsAreBinaryCopyTuplesWithNullsAndTextsAsTheyAre) {
    ForwardBatch batch;
    batch.add(3, t0, 21.5, std::nullopt, "ok");
    batch.add(3, t0 + 1000, std::nullopt, "a\tb\\c\r\nd \"é\"", std::nullopt);
    const auto tuples = tuples_of(batch.copy_data());
    ASSERT_EQ(tuples.size(), 2u);
    const std::vector<Field> first{big_endian(3), big_endian(static_cast<std::uint64_t>(t0)),
                                   big_endian(std::bit_cast<std::uint64_t>(21.5)), std::nullopt, "ok"};
    EXPECT_EQ(tuples[0], first);
    const std::vector<Field> second{big_endian(3), big_endian(static_cast<std::uint64_t>(t0 + 1000)), std::nullopt,
                                    "a\tb\\c\r\nd \"é\"", std::nullopt};
    EXPECT_EQ(tuples[1], second);
    EXPECT_EQ(batch.rows(), 2u);
    EXPECT_EQ(batch.days(), std::set<std::int64_t>{t0 / 86400000});
}

TEST(ForwardBatch, AnEmptyBatchIsAWholeCopyOfNoTuples) { EXPECT_TRUE(tuples_of(ForwardBatch().copy_data()).empty()); }

TEST(ForwardBatch, NegativeAndNonFiniteNumbersKeepTheirBits) {
    ForwardBatch batch;
    batch.add(1, -1, -std::numeric_limits<double>::infinity(), std::nullopt, std::nullopt);
    batch.add(1, 0, std::numeric_limits<double>::quiet_NaN(), std::nullopt, std::nullopt);
    const auto tuples = tuples_of(batch.copy_data());
    ASSERT_EQ(tuples.size(), 2u);
    EXPECT_EQ(tuples[0][1], big_endian(~std::uint64_t{0}));
    EXPECT_EQ(tuples[0][2], big_endian(std::bit_cast<std::uint64_t>(-std::numeric_limits<double>::infinity())));
    EXPECT_EQ(tuples[1][2], big_endian(std::bit_cast<std::uint64_t>(std::numeric_limits<double>::quiet_NaN())));
}

TEST(ForwardBatch, MinutesAreKeptPerSeriesAndMinuteFromTheValuesOnly) {
    ForwardBatch batch;
    for (int i = 0; i < 90; ++i) batch.add(1, t0 + i * 1000, i, std::nullopt, "ok");
    batch.add(1, t0 + 30500, std::nullopt, std::nullopt, "no-reply");  // no part of a minute
    batch.add(2, t0 - 1, -4, std::nullopt, "ok");                       // the minute before t0
    ASSERT_EQ(batch.minutes().size(), 3u);
    const MinuteRollup& first = batch.minutes().at({1, t0 / 60000});
    EXPECT_EQ(first.lo, 0);
    EXPECT_EQ(first.hi, 59);
    EXPECT_EQ(first.total, 1770);
    EXPECT_EQ(first.n, 60);
    EXPECT_EQ(batch.minutes().at({1, t0 / 60000 + 1}).n, 30);
    EXPECT_EQ(batch.minutes().at({2, t0 / 60000 - 1}).lo, -4);
    const auto columns = batch.minute_columns();
    ASSERT_EQ(columns.size(), 6u);
    EXPECT_EQ(*columns[0], "{\"1\",\"1\",\"2\"}");
    EXPECT_EQ(*columns[5], "{\"60\",\"30\",\"1\"}");
}

// PostgreSQL's min() and max() of float8 put NaN above every number: so does the rollup here,
// whatever order the values come in.
TEST(ForwardBatch, NanIsTheHighestValueAsInPostgresql) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    MinuteRollup nan_first, nan_last;
    for (double v : {nan, 5.0, -2.0}) nan_first.add(v);
    for (double v : {5.0, -2.0, nan}) nan_last.add(v);
    for (const MinuteRollup& rollup : {nan_first, nan_last}) {
        EXPECT_EQ(rollup.lo, -2);
        EXPECT_TRUE(std::isnan(rollup.hi));
        EXPECT_TRUE(std::isnan(rollup.total));
        EXPECT_EQ(rollup.n, 3);
    }
}

}  // namespace
}  // namespace loopwire::gateway
