// A device whose replies a relay holds back for a while (1 s, polled every 200 ms), then delivers
// on time again, on the gateway's own PollGroups, ValueCache and HistoryStore in virtual time (the
// lines' loop on a VirtualClock, as tests/gateway/line_soak_test.cpp runs them): the device goes
// stale with its poll in flight, again and again, and each late reply makes it `ok` again.
// Asserted: the history files each reply after the `stale` it ends (rows carry the time of the
// reply, not of the poll's start), the values that hold still get their heartbeats again at
// once, and the history query (what /api/history answers with) has no open gap while the
// device is `ok`.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "gateway/event_loop.hpp"
#include "gateway/gateway_config.hpp"
#include "gateway/history_schema.hpp"
#include "gateway/history_store.hpp"
#include "gateway/line_scheduler.hpp"
#include "gateway/poll_groups.hpp"
#include "gateway/reopening_master.hpp"
#include "gateway/value_cache.hpp"
#include "profile/profile.hpp"
#include "session/line_loop.hpp"
#include "session/master.hpp"
#include "session/slave.hpp"
#include "simulation/register_bank.hpp"
#include "simulation/simulated_lines.hpp"
#include "support/history_parts.hpp"
#include "support/history_test_support.hpp"
#include "support/virtual_time_wire.hpp"
#include "transport/link_url.hpp"

namespace loopwire::gateway {
namespace {

using namespace std::chrono_literals;
using Duration = Instant::duration;
using loopwire::testing::TempFolder;

constexpr auto poll_every = 200ms;
constexpr auto heartbeat = 1s;
// While the relay holds the replies back, each comes this late: more than the three intervals
// after which a device is stale (value_cache.hpp), less than the master's timeout.
constexpr Duration held_back = 1s;
constexpr Duration reply_timeout = 3s;
// Plant time from the start: the relay holds the replies back in [holding_from, holding_until).
// After the relay stops holding replies back the serial master still waits, for its next eight
// replies, as long as its last replies took (session/serial_master.cpp, ReplyLatency): the device
// keeps going stale for some 10 s more, each time with its poll in flight. The run goes on well
// past that, so that the device settles `ok` and its heartbeats show.
constexpr Duration holding_from = 2s;
constexpr Duration holding_until = 5s;
constexpr Duration run_for = 25s;
constexpr auto write_every = 100ms;  // the history's commits (its writer thread's, on the loop here)

const char* const link_text = "rtu:virtual?baud=19200&parity=none";

// Three plain words at holding registers 0 ... 2 that hold still: only heartbeats write them again.
std::shared_ptr<const device::Profile> plain_profile() {
    std::string parameters;
    for (int address = 0; address < 3; ++address) {
        parameters += fmt::format(
            R"({}{{"name": "p{}", "table": "holding", "address": {}, "type": "uint16", "unitless": "raw", "access": "r", "source": "test"}})",
            address == 0 ? "" : ", ", address, address);
    }
    const auto text = fmt::format(
        R"({{"id": "plain", "title": "plain device", "manual": {{"file": "none", "document": "none"}}, "protocols": ["rtu"],
            "serial_defaults": {{"baud": 19200, "data_bits": 8, "parity": "none", "stop_bits": 1}}, "function_codes": [3],
            "limits": {{"read_registers": 16, "write_registers": 16}}, "unmapped_reads": "exception",
            "addressing": {{"numbering": "wire addresses"}}, "identification": {{"match": [{{"parameter": "p0", "equals": 100}}]}},
            "parameters": [{}]}})",
        parameters);
    auto profile = device::load_profile_text(text, "plain.json");
    if (!profile) throw std::runtime_error(profile.error().message);
    return std::make_shared<const device::Profile>(std::move(*profile));
}

class Unit final : public session::UnitHandler {
public:
    Unit() {
        for (std::uint16_t address = 0; address < 3; ++address) {
            bank_.set(codec::Table::holding_registers, address, static_cast<std::uint16_t>(100 + address));
        }
    }
    std::optional<Bytes> handle(ByteView request_pdu, bool broadcast) override { return bank_.handle(request_pdu, broadcast); }

private:
    session::RegisterBank bank_;
};

GatewayConfig one_device() {
    GatewayConfig config;
    config.source = "test";
    LineConfig line;
    line.name = "plant";
    line.link = *transport::parse_link_url(link_text);
    DeviceConfig device;
    device.name = "oven";
    device.address = {plain_profile(), 3};
    device.poll = poll_every;
    device.parameters = {"p0", "p1", "p2"};
    line.devices.push_back(std::move(device));
    config.lines.push_back(std::move(line));
    return config;
}

// One row of the history file: its time and its status ("ok" for none).
struct Row {
    std::int64_t t = 0;
    std::string status;
};

std::vector<Row> rows_of(const std::filesystem::path& file, const std::string& parameter) {
    auto db = history::open_for_reading(file);
    if (!db) throw std::runtime_error(db.error().message);
    auto rows = db->prepare(
        "SELECT s.t, coalesce(s.status, 'ok') FROM samples s JOIN series r ON r.id = s.series_id WHERE r.parameter = ?1 "
        "ORDER BY s.t");
    if (!rows) throw std::runtime_error(rows.error().message);
    rows->bind(1, std::string_view(parameter));
    std::vector<Row> found;
    for (;;) {
        auto step = rows->step();
        if (!step) throw std::runtime_error(step.error().message);
        if (!*step) break;
        found.push_back({rows->integer(0), rows->text(1)});
    }
    return found;
}

std::int64_t ms_of(std::chrono::system_clock::time_point time) {
    return std::chrono::duration_cast<std::chrono::milliseconds>(time.time_since_epoch()).count();
}

// What the run left, gathered on the loop at its end with the clock held.
struct Outcome {
    device::DeviceStatus status = device::DeviceStatus::waiting;
    std::optional<std::chrono::milliseconds> since_answered;
    std::int64_t started_ms = 0;       // the wall time at the start
    std::int64_t holding_ended_ms = 0;  // the wall time when the relay stopped holding replies back
    std::int64_t ended_ms = 0;
    Result<std::vector<HistorySeries>> series = std::vector<HistorySeries>{};
    unsigned stale_told = 0;  // the changes to `stale` the history was told
    unsigned ok_after_stale = 0;  // ... and to `ok` right after one
    std::map<std::string, std::vector<Row>> rows;  // each parameter's rows in the file, by time
    std::vector<std::string> log;  // what the polls logged (GatewayLog), in order
};

class LateReplies {
public:
    explicit LateReplies(const std::filesystem::path& file)
        : file_(file), loop_(std::make_shared<session::LineLoop>(clock_)), simulated_(loop_) {}

    ~LateReplies() {
        hold_.reset();   // the plant's time goes on: the polls' reads in flight end
        polls_.reset();  // as ~Gateway: the polls, then what they wrote to
        recording_.reset();
        scheduler_.reset();
        master_.reset();
    }

    Outcome run() {
        const auto url = *transport::parse_link_url(link_text);
        master_ = std::make_shared<ReopeningMaster>(
            "plant", url.to_string(), [this, url] { return open(url); }, ReopenSchedule{}, clock_, LinkLog{},
            LinkConcurrency::on_loop, loop_);
        if (!master_->start()) throw std::runtime_error("the line did not start");
        scheduler_ = std::make_shared<LineScheduler>(master_, LineSchedulerOptions{}, clock_);
        cache_ = std::make_unique<ValueCache>(clock_, [this] { return events_.wall_now(); });
        loopwire::testing::HistoryPartsOptions options;
        options.database = file_;
        options.heartbeat = heartbeat;
        options.wall_clock = [this] { return events_.wall_now(); };
        auto opened = loopwire::testing::HistoryParts::open(std::move(options));
        if (!opened) throw std::runtime_error(opened.error().message);
        history_ = std::move(*opened);
        // As the gateway records: every change the cache tells goes to the history.
        recording_ = cache_->subscribe([this](const ValueChange& change) {
            if (over_) return;  // the outcome is the test's now
            if (change.about_device()) {
                if (change.status == "stale") ++outcome_.stale_told;
                if (change.status == "ok" && last_device_status_ == "stale") ++outcome_.ok_after_stale;
                last_device_status_ = change.status;
            }
            history_->record(change);
        });
        const GatewayConfig config = one_device();
        polls_ = std::make_unique<PollGroups>(events_, config, std::map<std::string, std::shared_ptr<LineScheduler>>{{"plant", scheduler_}},
                                              *cache_, [this](const std::string& line) {
                                                  if (!over_) outcome_.log.push_back(line);
                                              }, nullptr);
        std::promise<void> ended;
        auto done = ended.get_future();
        loop_->post([this, &ended] { begin(ended); });
        if (done.wait_for(120s) != std::future_status::ready) {
            ADD_FAILURE() << "the run did not end in 120 s of wall time";
            std::abort();  // the loop still refers to `ended`
        }
        return std::move(outcome_);
    }

private:
    Result<std::unique_ptr<session::Master>> open(const transport::LinkUrl& url) {
        wire_ = testing::VirtualTimeWire::create(*loop_, codec::CharacterTiming{url.serial.baud, url.serial.bits_per_character()},
                                                [this](Bytes frame, Instant sent) {
                                                    return std::vector<testing::WireDelivery>{
                                                        {holding_ ? sent + held_back : sent, std::move(frame)}};
                                                });
        session::UnitMap units;
        units[3] = std::make_shared<Unit>();
        if (auto served = simulated_.add(wire_->end(testing::VirtualTimeWire::devices), std::make_unique<session::Slave>(url, units));
            !served) {
            return served.error();
        }
        session::MasterOptions options;
        options.timeout = std::chrono::duration_cast<std::chrono::milliseconds>(reply_timeout);
        options.loop = loop_;
        return session::make_serial_master(wire_->end(testing::VirtualTimeWire::master), url, options);
    }

    void at(Instant when, std::function<void()> work) { loop_->wait(-1, when, std::move(work)); }

    // On the loop from here on.
    void begin(std::promise<void>& ended) {
        const Instant start = clock_->now();
        outcome_.started_ms = ms_of(events_.wall_now());
        at(start + holding_from, [this] { holding_ = true; });
        at(start + holding_until, [this] {
            holding_ = false;
            outcome_.holding_ended_ms = ms_of(events_.wall_now());
        });
        commit(start + write_every);
        at(start + run_for, [this, &ended] { end(ended); });
    }

    void commit(Instant when) {
        at(when, [this, when] {
            if (over_) return;
            if (auto written = history_->write_pending(); !written) ADD_FAILURE() << written.error().message;
            commit(when + write_every);
        });
    }

    void end(std::promise<void>& ended) {
        over_ = true;
        hold_ = loop_->hold_time();  // the plant's time stops here: nothing changes while the test looks
        if (auto written = history_->write_pending(); !written) ADD_FAILURE() << written.error().message;
        const CachedDevice device = cache_->snapshot().at(0);
        outcome_.status = device.state.status;
        outcome_.since_answered = device.since_answered;
        outcome_.ended_ms = ms_of(events_.wall_now());
        HistoryQuery query;
        query.device = "oven";
        query.from = std::chrono::system_clock::time_point(std::chrono::milliseconds(outcome_.started_ms));
        query.to = events_.wall_now();
        query.points = 1000;
        outcome_.series = history_->query(query);
        for (const std::string parameter : {"p0", "p1", "p2"}) outcome_.rows[parameter] = rows_of(file_, parameter);
        ended.set_value();
    }

    std::filesystem::path file_;
    std::shared_ptr<VirtualClock> clock_ = std::make_shared<VirtualClock>();
    std::shared_ptr<session::LineLoop> loop_;
    simulation::SimulatedLines simulated_;
    std::shared_ptr<testing::VirtualTimeWire> wire_;
    std::shared_ptr<ReopeningMaster> master_;
    std::shared_ptr<LineScheduler> scheduler_;
    LineLoopEvents events_{loop_};
    std::unique_ptr<ValueCache> cache_;
    std::unique_ptr<loopwire::testing::HistoryParts> history_;
    ValueSubscription recording_;
    std::unique_ptr<PollGroups> polls_;
    std::shared_ptr<void> hold_;
    Outcome outcome_;
    std::string last_device_status_;  // the loop's
    bool holding_ = false;            // the loop's: the relay holds replies back
    bool over_ = false;               // the loop's
};

TEST(StaleHistory, ADeviceStaleWithItsPollInFlightIsOkInItsHistoryFromTheReplyOnWithHeartbeatsAndNoOpenGap) {
    TempFolder folder;
    const auto file = folder.path / "plant.db";
    Outcome outcome;
    {
        LateReplies plant(file);
        outcome = plant.run();
    }
    std::printf("late replies: %u stale spells, each ended by its poll's reply; p0 has %zu rows\n", outcome.stale_told,
                outcome.rows["p0"].size());
    // The case arose: the device went stale with a poll in flight, and the late reply made it ok.
    EXPECT_GE(outcome.stale_told, 2u) << "the device never went stale while its replies were held back: the test proves nothing";
    EXPECT_EQ(outcome.ok_after_stale, outcome.stale_told);
    // The log says each spell at the level an operator filters on: going stale a warning, its
    // end a notice (app/gateway_log.hpp), one after the other.
    std::vector<std::string> spells;
    for (const std::string& line : outcome.log) {
        if (line.find("device oven is ") != std::string::npos) spells.push_back(line);
    }
    EXPECT_GE(spells.size(), 2u);
    for (std::size_t i = 0; i < spells.size(); ++i) {
        const std::string expected = i % 2 == 0 ? "warning: device oven is stale: " : "notice: device oven is polled again: ";
        EXPECT_EQ(spells[i].rfind(expected, 0), 0u) << spells[i];
    }
    ASSERT_NE(outcome.holding_ended_ms, 0);
    // What /api/devices says at the end: ok, answered within the last poll or so.
    EXPECT_EQ(outcome.status, device::DeviceStatus::ok);
    ASSERT_TRUE(outcome.since_answered);
    EXPECT_LT(*outcome.since_answered, 1s);

    for (const std::string parameter : {"p0", "p1", "p2"}) {
        SCOPED_TRACE(parameter);
        const std::vector<Row>& rows = outcome.rows[parameter];
        ASSERT_FALSE(rows.empty());
        // Each `stale` is followed by the reply that ended it, filed after it.
        std::size_t stale = 0, last_stale = 0;
        for (std::size_t i = 0; i < rows.size(); ++i) {
            if (rows[i].status != "stale") continue;
            ++stale;
            last_stale = i;
            ASSERT_LT(i + 1, rows.size()) << "a stale row is the last one: the reply that ended it was filed before it";
            EXPECT_EQ(rows[i + 1].status, "ok") << "at " << rows[i + 1].t - outcome.started_ms << " ms";
        }
        EXPECT_EQ(stale, outcome.stale_told);
        EXPECT_EQ(rows.back().status, "ok");
        // The value holds still: after the last stale row and the reply that ended it, only
        // heartbeats write it, one a heartbeat, up to the end.
        const std::int64_t resumed = rows[last_stale + 1].t;
        const auto heartbeats = static_cast<std::int64_t>(rows.size() - last_stale - 2);
        const std::int64_t expected = (outcome.ended_ms - resumed) / std::chrono::milliseconds(heartbeat).count();
        EXPECT_GE(heartbeats, expected - 1) << "heartbeats after the device came back from stale";
        EXPECT_GE(heartbeats, 5);
        EXPECT_GE(outcome.ended_ms - rows.back().t, 0);
        EXPECT_LE(outcome.ended_ms - rows.back().t, std::chrono::milliseconds(heartbeat + write_every).count());
    }

    // The history query, as /api/history asks it: every gap (each stale spell) has its end.
    ASSERT_TRUE(outcome.series) << outcome.series.error().message;
    ASSERT_EQ(outcome.series->size(), 3u);
    for (const HistorySeries& series : *outcome.series) {
        SCOPED_TRACE(series.parameter);
        EXPECT_EQ(series.gaps.size(), outcome.stale_told);
        for (const HistoryGap& gap : series.gaps) {
            ASSERT_TRUE(gap.end) << "an open gap from " << ms_of(gap.start) - outcome.started_ms
                                 << " ms while the device is ok";
            EXPECT_GE(ms_of(gap.start), outcome.started_ms + std::chrono::duration_cast<std::chrono::milliseconds>(holding_from).count());
        }
    }
}

}  // namespace
}  // namespace loopwire::gateway
