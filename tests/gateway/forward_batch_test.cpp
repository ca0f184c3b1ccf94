// The forwarder's batch (gateway/forward_batch.hpp): the rows in COPY's text format, and the
// minutes computed as PostgreSQL's own statement computes them (history_forward_test.cpp runs
// both against a real server).
#include "gateway/forward_batch.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace loopwire::gateway {
namespace {

constexpr std::int64_t t0 = 1767225600000;  // 2026-01-01T00:00:00Z, on a minute

TEST(ForwardBatch, RowsAreCopyTextWithNullsAndEscapes) {
    ForwardBatch batch;
    batch.add(3, t0, 21.5, std::nullopt, "ok");
    batch.add(3, t0 + 1000, std::nullopt, "a\tb\\c\r\nd", std::nullopt);
    EXPECT_EQ(batch.copy_text(), "3\t1767225600000\t21.5\t\\N\tok\n3\t1767225601000\t\\N\ta\\tb\\\\c\\r\\nd\t\\N\n");
    EXPECT_EQ(batch.rows(), 2u);
    EXPECT_EQ(batch.days(), std::set<std::int64_t>{t0 / 86400000});
}

TEST(ForwardBatch, NonFiniteValuesAreWrittenInPostgresqlsWords) {
    ForwardBatch batch;
    batch.add(1, t0, std::numeric_limits<double>::quiet_NaN(), std::nullopt, std::nullopt);
    batch.add(1, t0 + 1, std::numeric_limits<double>::infinity(), std::nullopt, std::nullopt);
    batch.add(1, t0 + 2, -std::numeric_limits<double>::infinity(), std::nullopt, std::nullopt);
    EXPECT_EQ(batch.copy_text(), "1\t1767225600000\tNaN\t\\N\t\\N\n1\t1767225600001\tInfinity\t\\N\t\\N\n"
                                 "1\t1767225600002\t-Infinity\t\\N\t\\N\n");
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
