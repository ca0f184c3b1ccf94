// The history store (gateway/history_store.hpp) on real SQLite files in a temporary folder:
// what is recorded is queried back exactly, heartbeats, special states, retention on virtual
// time, restarts, bad queries, files that are not a history, and a kill -9 while writing.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include <fmt/format.h>

#include "gateway/history_schema.hpp"
#include "gateway/history_store.hpp"
#include "support/eventually.hpp"
#include "support/history_parts.hpp"
#include "support/history_test_support.hpp"

extern char** environ;

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using std::chrono::milliseconds;
using loopwire::testing::HistoryParts;
using loopwire::testing::HistoryPartsOptions;
using loopwire::testing::TempFolder;
using loopwire::testing::eventually;
using loopwire::testing::VirtualWall;

// 2026-01-01T00:00:00Z: a round minute, so bucket starts are easy to read.
const SystemTime t0 = SystemTime(std::chrono::seconds(1767225600));

HistoryPartsOptions options_at(const std::filesystem::path& file, const VirtualWall& wall) {
    HistoryPartsOptions options;
    options.database = file;
    options.wall_clock = wall.clock();
    return options;
}

ValueChange number(const std::string& parameter, double value, SystemTime sampled, const std::string& unit = "°C") {
    ValueChange change;
    change.device = "oven1";
    change.parameter = parameter;
    change.unit = unit;
    change.status = "ok";
    change.value = device::EngineeringValue{value, "ok", 0, ""};
    change.text = fmt::format("{:.1f}", value);
    change.sampled = sampled;
    return change;
}

ValueChange special(const std::string& parameter, const std::string& status, SystemTime sampled, bool with_value) {
    ValueChange change;
    change.device = "oven1";
    change.parameter = parameter;
    change.unit = "°C";
    change.status = status;
    if (with_value) change.value = device::EngineeringValue{std::monostate{}, status, 0x8000, ""};  // a special state's word
    else change.error = "no reply";
    change.sampled = sampled;
    return change;
}

HistoryQuery ask(const std::string& parameter, SystemTime from, SystemTime to, std::size_t points) {
    HistoryQuery query;
    query.device = "oven1";
    if (!parameter.empty()) query.parameters = {parameter};
    query.from = from;
    query.to = to;
    query.points = points;
    return query;
}

std::unique_ptr<HistoryParts> open_store(HistoryPartsOptions options, const std::vector<HistorySeriesName>& declared = {}) {
    auto store = HistoryParts::open(std::move(options), declared);
    EXPECT_TRUE(store) << store.error().message;
    return store ? std::move(*store) : nullptr;
}

TEST(HistoryStore, ChangesAreQueriedBackWithExactMinMaxMean) {
    TempFolder folder;
    VirtualWall wall(t0);
    auto store = open_store(options_at(folder.path / "plant.db", wall));
    ASSERT_TRUE(store);
    store->record(number("measured_value", 10, t0));
    store->record(number("measured_value", 20, t0 + 1s));
    store->record(number("measured_value", 33, t0 + 2s));
    store->record(number("measured_value", -4.5, t0 + 12s));
    store->record(number("set_point", 250, t0 + 1s));
    ASSERT_TRUE(store->write_pending());
    EXPECT_EQ(store->rows_written(), 5u);

    auto series = store->query(ask("measured_value", t0, t0 + 20s - 1ms, 2));
    ASSERT_TRUE(series) << series.error().message;
    ASSERT_EQ(series->size(), 1u);
    EXPECT_EQ((*series)[0].parameter, "measured_value");
    EXPECT_EQ((*series)[0].unit, "°C");
    const auto& buckets = (*series)[0].buckets;
    ASSERT_EQ(buckets.size(), 2u);
    EXPECT_EQ(buckets[0].start, t0);
    EXPECT_EQ(buckets[0].count, 3u);
    EXPECT_EQ(buckets[0].min, 10);
    EXPECT_EQ(buckets[0].max, 33);
    EXPECT_DOUBLE_EQ(buckets[0].mean, 21);
    EXPECT_EQ(buckets[1].start, t0 + 10s);
    EXPECT_EQ(buckets[1].count, 1u);
    EXPECT_EQ(buckets[1].min, -4.5);
    EXPECT_EQ(buckets[1].max, -4.5);

    // No parameter named: every one recorded, in the order first seen.
    auto all = store->query(ask("", t0, t0 + 20s, 1));
    ASSERT_TRUE(all) << all.error().message;
    ASSERT_EQ(all->size(), 2u);
    EXPECT_EQ((*all)[1].parameter, "set_point");
    ASSERT_EQ((*all)[1].buckets.size(), 1u);
    EXPECT_EQ((*all)[1].buckets[0].mean, 250);
}

TEST(HistoryStore, AnEnumLabelKeepsItsRawNumberAndItsText) {
    TempFolder folder;
    VirtualWall wall(t0);
    const auto file = folder.path / "plant.db";
    {
        auto store = open_store(options_at(file, wall));
        ASSERT_TRUE(store);
        ValueChange mode = number("control_mode", 0, t0, "");
        mode.value = device::EngineeringValue{std::string("manual"), "ok", 2, ""};
        mode.text = "manual";
        store->record(mode);
        ASSERT_TRUE(store->write_pending());
        auto series = store->query(ask("control_mode", t0, t0 + 1s, 10));
        ASSERT_TRUE(series) << series.error().message;
        ASSERT_EQ((*series)[0].buckets.size(), 1u);
        EXPECT_EQ((*series)[0].buckets[0].mean, 2);
    }
    auto db = history::open_for_reading(file);
    ASSERT_TRUE(db);
    EXPECT_EQ(*db->query_text("SELECT text FROM samples"), "manual");
}

TEST(HistoryStore, AHeartbeatRewritesAValueThatHoldsStill) {
    TempFolder folder;
    VirtualWall wall(t0);
    auto options = options_at(folder.path / "plant.db", wall);
    options.heartbeat = 60s;
    auto store = open_store(options);
    ASSERT_TRUE(store);
    store->record(number("measured_value", 137, t0));
    ASSERT_TRUE(store->write_pending());
    wall.set(t0 + 59s);
    ASSERT_TRUE(store->write_pending());
    EXPECT_EQ(store->rows_written(), 1u);  // not due yet
    wall.set(t0 + 60s);
    ASSERT_TRUE(store->write_pending());
    EXPECT_EQ(store->rows_written(), 2u);
    wall.set(t0 + 150s);
    ASSERT_TRUE(store->write_pending());
    EXPECT_EQ(store->rows_written(), 3u);

    auto series = store->query(ask("measured_value", t0, t0 + 180s - 1ms, 3));
    ASSERT_TRUE(series) << series.error().message;
    const auto& buckets = (*series)[0].buckets;
    ASSERT_EQ(buckets.size(), 3u);  // one per minute: no gap in the flat line
    for (const auto& bucket : buckets) EXPECT_EQ(bucket.mean, 137);
    EXPECT_EQ(buckets[2].start, t0 + 120s);
}

// A row that says nothing was read is never stamped again by a heartbeat: the present would
// be put on a reading nobody made. Whatever the reason: no reply, a line down, an overdue poll.
TEST(HistoryStore, AHeartbeatNeverRepeatsARowOfNothingRead) {
    for (const char* status : {"no-reply", "line-down", "stale", "waiting", "error"}) {
        TempFolder folder;
        VirtualWall wall(t0);
        auto options = options_at(folder.path / "plant.db", wall);
        options.heartbeat = 60s;
        auto store = open_store(options);
        ASSERT_TRUE(store);
        store->record(special("measured_value", status, t0, false));
        ASSERT_TRUE(store->write_pending());
        wall.set(t0 + 180s);
        ASSERT_TRUE(store->write_pending());
        EXPECT_EQ(store->rows_written(), 1u) << status << " was repeated by a heartbeat";
    }
}

TEST(HistoryStore, SpecialStatesAreRowsButNoPartOfTheBuckets) {
    TempFolder folder;
    VirtualWall wall(t0);
    auto store = open_store(options_at(folder.path / "plant.db", wall));
    ASSERT_TRUE(store);
    store->record(number("measured_value", 1, t0));
    store->record(special("measured_value", "under-range", t0 + 1s, true));
    store->record(special("measured_value", "no-reply", t0 + 2s, false));
    store->record(number("measured_value", 3, t0 + 3s));
    store->record(special("set_point", "not-available", t0, true));  // nothing but a special state
    ASSERT_TRUE(store->write_pending());
    EXPECT_EQ(store->rows_written(), 5u);

    auto series = store->query(ask("", t0, t0 + 10s, 1));
    ASSERT_TRUE(series) << series.error().message;
    ASSERT_EQ(series->size(), 2u);
    ASSERT_EQ((*series)[0].buckets.size(), 1u);
    EXPECT_EQ((*series)[0].buckets[0].count, 2u);
    EXPECT_EQ((*series)[0].buckets[0].min, 1);
    EXPECT_EQ((*series)[0].buckets[0].max, 3);
    EXPECT_EQ((*series)[0].buckets[0].mean, 2);
    EXPECT_TRUE((*series)[1].buckets.empty());
    // The minute table agrees (a day in 10 buckets reads it).
    auto wide = store->query(ask("measured_value", t0, t0 + 24h, 10));
    ASSERT_TRUE(wide) << wide.error().message;
    ASSERT_EQ((*wide)[0].buckets.size(), 1u);
    EXPECT_EQ((*wide)[0].buckets[0].count, 2u);
    EXPECT_EQ((*wide)[0].buckets[0].mean, 2);
}

// Values are recorded on change: a time without a value is told apart from one where the value
// held, as gaps from a sample without a value to the next with one, whatever the buckets.
TEST(HistoryStore, GapsRunFromASampleWithoutAValueToTheNextWithOne) {
    TempFolder folder;
    VirtualWall wall(t0);
    auto store = open_store(options_at(folder.path / "plant.db", wall));
    ASSERT_TRUE(store);
    store->record(number("measured_value", 180, t0));
    store->record(special("measured_value", "no-reply", t0 + 10s, false));
    store->record(special("measured_value", "no-reply", t0 + 20s, false));  // the same outage, said again
    store->record(number("measured_value", 25, t0 + 3min));
    store->record(number("measured_value", 26, t0 + 4min));  // held from 3 min to 4 min: no gap
    store->record(special("measured_value", "under-range", t0 + 5min, true));  // a special state has no number either
    ASSERT_TRUE(store->write_pending());
    const auto at = [](std::chrono::seconds offset) { return t0 + offset; };

    auto series = store->query(ask("measured_value", t0, t0 + 10min, 1));
    ASSERT_TRUE(series) << series.error().message;
    const auto& gaps = (*series)[0].gaps;
    ASSERT_EQ(gaps.size(), 2u);
    EXPECT_EQ(gaps[0].start, at(10s));
    ASSERT_TRUE(gaps[0].end);
    EXPECT_EQ(*gaps[0].end, at(3min));
    EXPECT_EQ(gaps[1].start, at(5min));
    EXPECT_FALSE(gaps[1].end) << "the under-range state lasts: no sample with a value came after it";

    // Asked from inside the outage: the gap is open at `from`.
    auto inside = store->query(ask("measured_value", t0 + 1min, t0 + 4min, 10));
    ASSERT_TRUE(inside) << inside.error().message;
    ASSERT_EQ((*inside)[0].gaps.size(), 1u);
    EXPECT_EQ((*inside)[0].gaps[0].start, at(1min));
    EXPECT_EQ((*inside)[0].gaps[0].end, std::optional(at(3min)));
    // From where the value holds: no gap, though no sample is in the range.
    auto held = store->query(ask("measured_value", at(200s), at(230s), 10));
    ASSERT_TRUE(held) << held.error().message;
    EXPECT_TRUE((*held)[0].gaps.empty());
    EXPECT_TRUE((*held)[0].buckets.empty());
}

// Values are recorded on change (and a heartbeat): a value that held since before `from` has no
// row at `from`, so each series carries the last row before it, the value in force there, which
// is where a chart's line starts. Not a bucket: the buckets' statistics stay the range's own.
TEST(HistoryStore, AValueRecordedBeforeFromIsTheValueInForceAtFrom) {
    TempFolder folder;
    VirtualWall wall(t0);
    auto options = options_at(folder.path / "plant.db", wall);
    options.heartbeat = 60s;
    auto store = open_store(options);
    ASSERT_TRUE(store);
    store->record(number("measured_value", 137, t0));
    store->record(number("measured_value", 140, t0 + 50s));
    store->record(number("measured_value", 150, t0 + 100s));
    ASSERT_TRUE(store->write_pending());

    // The 5 minutes from t0 + 30 s: 137 holds there, recorded 30 s before.
    auto series = store->query(ask("measured_value", t0 + 30s, t0 + 330s, 600));
    ASSERT_TRUE(series) << series.error().message;
    ASSERT_TRUE((*series)[0].before);
    EXPECT_EQ((*series)[0].before->time, t0);
    EXPECT_EQ((*series)[0].before->value, 137);
    ASSERT_EQ((*series)[0].buckets.size(), 2u) << "the buckets are the rows inside the range only";
    EXPECT_EQ((*series)[0].buckets[0].mean, 140);
    EXPECT_TRUE((*series)[0].gaps.empty());
    // The last row before `from`, not the first: from t0 + 60 s, 140.
    auto later = store->query(ask("measured_value", t0 + 60s, t0 + 360s, 600));
    ASSERT_TRUE(later) << later.error().message;
    ASSERT_TRUE((*later)[0].before);
    EXPECT_EQ((*later)[0].before->time, t0 + 50s);
    EXPECT_EQ((*later)[0].before->value, 140);
    // Wide buckets (the minute table) carry it the same.
    auto wide = store->query(ask("measured_value", t0 + 30s, t0 + 24h, 10));
    ASSERT_TRUE(wide) << wide.error().message;
    ASSERT_TRUE((*wide)[0].before);
    EXPECT_EQ((*wide)[0].before->value, 137);
    // A value holding still is written again each heartbeat: its heartbeat is the row before.
    wall.set(t0 + 100s + 60s);
    ASSERT_TRUE(store->write_pending());
    auto held = store->query(ask("measured_value", t0 + 200s, t0 + 500s, 600));
    ASSERT_TRUE(held) << held.error().message;
    ASSERT_TRUE((*held)[0].before);
    EXPECT_EQ((*held)[0].before->time, t0 + 160s);
    EXPECT_EQ((*held)[0].before->value, 150);
    EXPECT_TRUE((*held)[0].buckets.empty());
}

// A row saying nothing was read (or a special state) before `from`: the line starts broken, with
// the gap open at `from`, not with the value before it.
TEST(HistoryStore, ARowOfNothingReadBeforeFromGivesNoValueInForce) {
    for (const char* status : {"no-reply", "line-down", "stale", "waiting", "error", "under-range"}) {
        TempFolder folder;
        VirtualWall wall(t0);
        auto store = open_store(options_at(folder.path / "plant.db", wall));
        ASSERT_TRUE(store);
        store->record(number("measured_value", 137, t0));
        store->record(special("measured_value", status, t0 + 10s, std::string(status) == "under-range"));
        ASSERT_TRUE(store->write_pending());
        auto series = store->query(ask("measured_value", t0 + 30s, t0 + 330s, 600));
        ASSERT_TRUE(series) << series.error().message;
        EXPECT_FALSE((*series)[0].before) << status;
        ASSERT_EQ((*series)[0].gaps.size(), 1u) << status;
        EXPECT_EQ((*series)[0].gaps[0].start, t0 + 30s) << status;
    }
    // A stale row that kept the last value is still no value read.
    TempFolder folder;
    VirtualWall wall(t0);
    auto store = open_store(options_at(folder.path / "plant.db", wall));
    ASSERT_TRUE(store);
    ValueChange stale = number("measured_value", 137, t0);
    stale.status = "stale";
    store->record(stale);
    ASSERT_TRUE(store->write_pending());
    auto series = store->query(ask("measured_value", t0 + 30s, t0 + 330s, 600));
    ASSERT_TRUE(series) << series.error().message;
    EXPECT_FALSE((*series)[0].before);
}

// The look-back is twice the heartbeat: a value still read is written again each heartbeat, so
// a last row older than that means nothing was recorded since (the gateway was stopped), and no
// value is known at `from`.
TEST(HistoryStore, ARowOlderThanTwoHeartbeatsGivesNoValueInForce) {
    TempFolder folder;
    VirtualWall wall(t0);
    auto options = options_at(folder.path / "plant.db", wall);
    options.heartbeat = 60s;
    auto store = open_store(options);
    ASSERT_TRUE(store);
    store->record(number("measured_value", 137, t0));
    ASSERT_TRUE(store->write_pending());
    auto within = store->query(ask("measured_value", t0 + 120s, t0 + 420s, 600));
    ASSERT_TRUE(within) << within.error().message;
    ASSERT_TRUE((*within)[0].before) << "120 s after the row: within two heartbeats";
    EXPECT_EQ((*within)[0].before->value, 137);
    auto older = store->query(ask("measured_value", t0 + 120s + 1ms, t0 + 420s, 600));
    ASSERT_TRUE(older) << older.error().message;
    EXPECT_FALSE((*older)[0].before) << "older than two heartbeats";
    EXPECT_TRUE((*older)[0].gaps.empty()) << "not a gap either: nothing is known";

    // The bound follows the configured heartbeat.
    TempFolder other;
    auto slow_options = options_at(other.path / "plant.db", wall);
    slow_options.heartbeat = 10min;
    auto slow = open_store(slow_options);
    ASSERT_TRUE(slow);
    slow->record(number("measured_value", 42, t0));
    ASSERT_TRUE(slow->write_pending());
    auto late = slow->query(ask("measured_value", t0 + 15min, t0 + 20min, 600));
    ASSERT_TRUE(late) << late.error().message;
    ASSERT_TRUE((*late)[0].before);
    EXPECT_EQ((*late)[0].before->value, 42);
}

// Three hours at 1 s with spikes, asked for in buckets that start mid-minute, so that every
// bucket mixes minute rows and samples: each must equal what the samples alone give.
TEST(HistoryStore, WideBucketsFromTheMinuteTableMatchTheSamples) {
    TempFolder folder;
    VirtualWall wall(t0);
    auto store = open_store(options_at(folder.path / "plant.db", wall));
    ASSERT_TRUE(store);
    std::vector<std::pair<std::int64_t, double>> values;
    std::mt19937 random(7);
    std::uniform_real_distribution<double> noise(-1.0, 1.0);
    for (int s = 0; s < 3 * 3600; ++s) {
        double value = 100 + 10 * std::sin(s / 600.0) + noise(random);
        if (s % 977 == 0) value += 50;  // spikes the mean would hide
        const SystemTime at = t0 + std::chrono::seconds(s);
        store->record(number("measured_value", value, at));
        values.emplace_back(s * 1000, value);
    }
    ASSERT_TRUE(store->write_pending());
    const SystemTime from = t0 + 1234567ms;
    const SystemTime to = t0 + 3h - 4321ms;
    const std::size_t points = 37;
    auto series = store->query(ask("measured_value", from, to, points));
    ASSERT_TRUE(series) << series.error().message;
    const auto& buckets = (*series)[0].buckets;
    ASSERT_LE(buckets.size(), points);
    const auto ms = [](SystemTime time) { return std::chrono::duration_cast<milliseconds>(time - t0).count(); };
    // 2.6 h into 37: 255.5 s, rounded up to 5 whole minutes, from the minute `from` falls in.
    const std::int64_t width = ms(buckets[1].start) - ms(buckets[0].start);
    EXPECT_EQ(width, 300000);
    EXPECT_EQ(ms(buckets[0].start), 1200000);
    EXPECT_EQ(buckets.size(), 32u);  // (to - 20 min) / 5 min, rounded up: every one has samples
    std::size_t total = 0;
    for (const auto& bucket : buckets) {
        const std::int64_t start = std::max(ms(bucket.start), ms(from));
        const std::int64_t end = std::min(ms(bucket.start) + width - 1, ms(to));
        double lo = 1e300, hi = -1e300, sum = 0;
        std::size_t count = 0;
        for (const auto& [t, v] : values) {
            if (t < start || t > end) continue;
            lo = std::min(lo, v);
            hi = std::max(hi, v);
            sum += v;
            ++count;
        }
        EXPECT_EQ(bucket.count, count) << "bucket at " << ms(bucket.start);
        EXPECT_EQ(bucket.min, lo);
        EXPECT_EQ(bucket.max, hi);
        EXPECT_NEAR(bucket.mean, sum / static_cast<double>(count), 1e-9);
        total += count;
    }
    EXPECT_EQ(total, static_cast<std::size_t>(std::count_if(values.begin(), values.end(), [&](const auto& value) {
                  return value.first >= ms(from) && value.first <= ms(to);
              })));
}

TEST(HistoryStore, RetentionDeletesOldRowsInSmallBatchesOnVirtualTime) {
    TempFolder folder;
    VirtualWall wall(t0);
    auto options = options_at(folder.path / "plant.db", wall);
    options.keep = 1h;
    options.heartbeat = 24h;
    auto store = open_store(options);
    ASSERT_TRUE(store);
    // 12 000 rows at 100 ms over the first 20 minutes, all written before any is due to go.
    for (int i = 0; i < 12000; ++i) store->record(number("measured_value", i, t0 + i * 100ms));
    ASSERT_TRUE(store->write_pending());
    auto db = history::open_for_reading(folder.path / "plant.db");
    ASSERT_TRUE(db);
    const auto count_all = [&] {
        auto count = db->query_integer("SELECT count(*) FROM samples");
        EXPECT_TRUE(count) << count.error().message;
        return count ? static_cast<std::size_t>(*count) : 0;
    };
    EXPECT_EQ(count_all(), 12000u);

    // 80 minutes on, all of it is older than the hour kept. Each write deletes one batch at
    // most, so the writer never stalls behind a long sweep.
    wall.set(t0 + 80min);
    store->record(number("measured_value", -1, t0 + 80min));
    ASSERT_TRUE(store->write_pending());
    // The cutoff is t0+20min: rows before it go, in batches of 5000.
    const std::size_t after_one = count_all();
    EXPECT_EQ(after_one, 12001u - 5000u);
    ASSERT_TRUE(store->write_pending());
    EXPECT_EQ(count_all(), 12001u - 10000u);
    ASSERT_TRUE(store->write_pending());
    EXPECT_EQ(count_all(), 1u);  // the new row is kept
    // Nothing is swept again until the interval passes, and then nothing more is due.
    ASSERT_TRUE(store->write_pending());
    EXPECT_EQ(count_all(), 1u);
    auto left = store->query(ask("measured_value", t0, t0 + 2h, 1));
    ASSERT_TRUE(left);
    EXPECT_EQ((*left)[0].buckets[0].min, -1);
    // The minute table went too: a wide query of the old range finds nothing.
    auto old = store->query(ask("measured_value", t0, t0 + 20min - 1ms, 1));
    ASSERT_TRUE(old);
    EXPECT_TRUE((*old)[0].buckets.empty());
}

TEST(HistoryStore, EnforceRetentionSweepsEverythingDue) {
    TempFolder folder;
    VirtualWall wall(t0);
    auto options = options_at(folder.path / "plant.db", wall);
    options.keep = 1h;
    auto store = open_store(options);
    ASSERT_TRUE(store);
    for (int i = 0; i < 7200; ++i) store->record(number("measured_value", i, t0 + i * 1s));  // two hours
    ASSERT_TRUE(store->write_pending());
    wall.set(t0 + 2h);
    ASSERT_TRUE(store->enforce_retention());
    auto series = store->query(ask("measured_value", t0, t0 + 2h, 1));
    ASSERT_TRUE(series);
    EXPECT_EQ((*series)[0].buckets[0].count, 3600u);
    EXPECT_EQ((*series)[0].buckets[0].min, 3600);
}

TEST(HistoryStore, AReopenedDatabaseAppendsToTheSameSeries) {
    TempFolder folder;
    VirtualWall wall(t0);
    const auto file = folder.path / "plant.db";
    {
        auto store = open_store(options_at(file, wall));
        ASSERT_TRUE(store);
        store->record(number("measured_value", 10, t0));
        // Not written by hand: closing the store writes what is queued.
    }
    {
        auto store = open_store(options_at(file, wall));
        ASSERT_TRUE(store);
        EXPECT_EQ(store->rows_written(), 0u);  // counted since this start
        store->record(number("measured_value", 30, t0 + 1s));
        ASSERT_TRUE(store->write_pending());
        auto series = store->query(ask("measured_value", t0, t0 + 2s, 1));
        ASSERT_TRUE(series) << series.error().message;
        ASSERT_EQ((*series)[0].buckets.size(), 1u);
        EXPECT_EQ((*series)[0].buckets[0].count, 2u);
        EXPECT_EQ((*series)[0].buckets[0].mean, 20);
    }
    auto db = history::open_for_reading(file);
    ASSERT_TRUE(db);
    EXPECT_EQ(*db->query_integer("SELECT count(*) FROM series"), 1);
}

TEST(HistoryStore, BadQueriesSayWhatWasWrong) {
    TempFolder folder;
    VirtualWall wall(t0);
    auto store = open_store(options_at(folder.path / "plant.db", wall), {{"oven1", "set_point", "°C"}});
    ASSERT_TRUE(store);
    store->record(number("measured_value", 10, t0));
    ASSERT_TRUE(store->write_pending());

    HistoryQuery unknown_device = ask("", t0, t0 + 1s, 10);
    unknown_device.device = "oven9";
    auto device = store->query(unknown_device);
    ASSERT_FALSE(device);
    EXPECT_EQ(device.error().kind, ErrorKind::usage);
    EXPECT_EQ(device.error().message, "no history of a device named \"oven9\" (devices recorded: oven1)");

    auto parameter = store->query(ask("valve", t0, t0 + 1s, 10));
    ASSERT_FALSE(parameter);
    EXPECT_EQ(parameter.error().message,
              "device \"oven1\" has no history of a parameter named \"valve\" (recorded: set_point, measured_value)");

    auto backwards = store->query(ask("measured_value", t0 + 1s, t0, 10));
    ASSERT_FALSE(backwards);
    EXPECT_THAT(backwards.error().message, HasSubstr("`from` is after its `to`"));

    auto none = store->query(ask("measured_value", t0, t0 + 1s, 0));
    ASSERT_FALSE(none);
    EXPECT_THAT(none.error().message, HasSubstr("ask for 1 to 10000 points"));

    // Declared but not yet read: an empty series, not an error.
    auto declared = store->query(ask("set_point", t0, t0 + 1s, 10));
    ASSERT_TRUE(declared) << declared.error().message;
    EXPECT_TRUE((*declared)[0].buckets.empty());
}

std::string open_error(const std::filesystem::path& file) {
    HistoryPartsOptions options;
    options.database = file;
    auto store = HistoryParts::open(options);
    return store ? std::string("opened") : store.error().message;
}

TEST(HistoryStore, AFileThatIsNotAHistoryIsRefusedClearly) {
    TempFolder folder;
    const auto noise = folder.path / "noise.db";
    {
        std::ofstream out(noise, std::ios::binary);
        std::mt19937 random(3);
        for (int i = 0; i < 8192; ++i) out.put(static_cast<char>(random() & 0xFF));
    }
    EXPECT_THAT(open_error(noise), HasSubstr(fmt::format("history database {}: cannot be read as an SQLite database", noise.string())));
    EXPECT_THAT(open_error(noise), HasSubstr("move the damaged file away"));

    const auto other = folder.path / "other.db";
    {
        auto db = sqlite::Connection::open(other.string(), sqlite::Connection::Mode::read_write_create);
        ASSERT_TRUE(db);
        ASSERT_TRUE(db->execute("CREATE TABLE invoices(id INTEGER)"));
    }
    EXPECT_EQ(open_error(other), fmt::format("history database {}: is an SQLite database of another program, not a loopwire "
                                             "history; name another file in [history] database", other.string()));

    EXPECT_THAT(open_error(folder.path / "missing" / "plant.db"), HasSubstr("does not exist; create it"));
    EXPECT_THAT(open_error(folder.path), HasSubstr("is a folder"));
    // Truncated to its first page: the header promises pages that are not there.
    const auto good = folder.path / "good.db";
    {
        VirtualWall wall(t0);
        auto store = open_store(options_at(good, wall));
        ASSERT_TRUE(store);
        for (int i = 0; i < 5000; ++i) store->record(number("measured_value", i, t0 + i * 1s));
    }
    std::filesystem::resize_file(good, 100);
    EXPECT_NE(open_error(good), "opened");
}

// A writer process (history_crash_writer) killed with SIGKILL while it records a value every
// millisecond: the file is whole, and everything it recorded more than a second before the
// kill is in it.
TEST(HistoryStore, KillNineWhileWritingLosesAtMostTheLastSecond) {
    TempFolder folder;
    const auto file = folder.path / "plant.db";
    int out[2];
    ASSERT_EQ(pipe(out), 0);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, out[0]);
    std::string program = HISTORY_CRASH_WRITER;
    std::string path = file.string();
    char* argv[] = {program.data(), path.data(), nullptr};
    pid_t child = 0;
    ASSERT_EQ(posix_spawn(&child, program.c_str(), &actions, nullptr, argv, environ), 0);
    posix_spawn_file_actions_destroy(&actions);
    close(out[1]);
    FILE* progress = fdopen(out[0], "r");
    ASSERT_NE(progress, nullptr);

    // Lines "N STEADY_MS": values 0..N were recorded by then. Read for 2.5 s of its writing.
    std::vector<std::pair<long long, long long>> recorded;
    const auto read_line = [&] {
        long long n = 0, at = 0;
        if (fscanf(progress, "%lld %lld", &n, &at) != 2) return false;
        recorded.emplace_back(n, at);
        return true;
    };
    const auto started = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() - started < 2500ms) {
        if (!read_line()) break;
    }
    const long long killed_at =
        std::chrono::duration_cast<milliseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
    ASSERT_EQ(kill(child, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the writer ended before it was killed";
    while (read_line()) {
    }
    fclose(progress);
    ASSERT_FALSE(recorded.empty()) << "the writer never reported progress";

    long long safe = -1;  // the last value recorded a second or more before the kill
    for (const auto& [n, at] : recorded) {
        if (at <= killed_at - 1000) safe = std::max(safe, n);
    }
    ASSERT_GE(safe, 0) << "the writer made no progress in its first 1.5 s";

    auto db = sqlite::Connection::open(file.string(), sqlite::Connection::Mode::read_write_create);
    ASSERT_TRUE(db);
    auto integrity = db->query_text("PRAGMA integrity_check");
    ASSERT_TRUE(integrity) << integrity.error().message;
    EXPECT_EQ(*integrity, "ok");
    auto kept = db->query_integer(fmt::format("SELECT count(*) FROM samples WHERE value <= {}", safe));
    ASSERT_TRUE(kept) << kept.error().message;
    EXPECT_EQ(*kept, safe + 1) << "values 0.." << safe << " were recorded at least a second before the kill";
    // And the store opens it again and goes on.
    HistoryPartsOptions options;
    options.database = file;
    auto reopened = HistoryParts::open(options);
    ASSERT_TRUE(reopened) << reopened.error().message;
}

TEST(HistoryStore, TheWriterThreadCommitsWithinASecond) {
    TempFolder folder;
    HistoryPartsOptions options;
    options.database = folder.path / "plant.db";
    options.reader_thread = true;
    auto store = open_store(options);
    ASSERT_TRUE(store);
    store->store->start();
    const auto now = std::chrono::system_clock::now();
    store->record(number("measured_value", 42, now));
    ASSERT_TRUE(eventually([&] { return store->rows_written() > 0; }, 10s)) << "the writer thread wrote nothing in 10 s";
    ASSERT_EQ(store->rows_written(), 1u);
    auto series = store->query(ask("measured_value", now - 1s, now + 1s, 1));
    ASSERT_TRUE(series) << series.error().message;
    EXPECT_EQ((*series)[0].buckets[0].mean, 42);
}

}  // namespace
}  // namespace loopwire::gateway
