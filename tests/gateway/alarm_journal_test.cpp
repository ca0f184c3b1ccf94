// The alarm journal in a history file: rows, states across a restart, a burst in one commit.
#include <gtest/gtest.h>

#include <filesystem>

#include "gateway/alarms/alarm_journal.hpp"
#include "gateway/history_schema.hpp"
#include "gateway/history_store.hpp"

namespace loopwire::gateway::alarms {
namespace {

using namespace std::chrono_literals;

struct TempFile {
    std::filesystem::path path;
    explicit TempFile(const std::string& name)
        : path(std::filesystem::temp_directory_path() / (name + "-" + std::to_string(::getpid()) + ".db")) {
        remove();
    }
    ~TempFile() { remove(); }
    void remove() const {
        for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path.string() + suffix);
    }
};

// Stamped now: the journal's rows older than [history] keep are deleted as it writes.
const Time t0 = std::chrono::time_point_cast<milliseconds>(std::chrono::system_clock::now()) - 1h;

LimitAlarm high_limit(const std::string& parameter, double limit) {
    LimitAlarm alarm;
    alarm.name = parameter + "_high";
    alarm.device = "oven";
    alarm.parameter = parameter;
    alarm.limit = limit;
    return alarm;
}

std::vector<JournalRow> all_rows(const std::filesystem::path& file) {
    auto db = history::open_for_reading(file);
    EXPECT_TRUE(db) << db.error().message;
    auto rows = read_journal(*db, t0 - 1h, t0 + 24h, 100000);
    EXPECT_TRUE(rows) << rows.error().message;
    return *rows;
}

TEST(AlarmJournal, EachTransitionIsARowWithItsUserAndComment) {
    TempFile file("alarm-journal-rows");
    auto journal = AlarmJournal::open(file.path);
    ASSERT_TRUE(journal) << journal.error().message;
    AlarmEngine engine({high_limit("temperature", 250)}, {"oven"});
    (*journal)->append(engine.feed("oven", "temperature", 260.0, "ok", "°C", t0));
    (*journal)->append(engine.acknowledge("oven.temperature_high", "ann", "on my way, \"now\"", t0 + 1s).transitions);
    ASSERT_TRUE((*journal)->write_pending());
    const auto rows = all_rows(file.path);
    ASSERT_EQ(rows.size(), 2U);
    EXPECT_EQ(rows[0].state, "active-acknowledged");  // newest first
    EXPECT_EQ(rows[0].user, "ann");
    EXPECT_EQ(rows[0].comment, "on my way, \"now\"");
    EXPECT_EQ(rows[1].state, "active-unacknowledged");
    EXPECT_EQ(rows[1].id, "oven.temperature_high");
    EXPECT_EQ(rows[1].parameter, "temperature");
    EXPECT_EQ(rows[1].value, 260.0);
    EXPECT_EQ(rows[1].unit, "°C");
    EXPECT_EQ(rows[1].severity, "medium");
    EXPECT_EQ(rows[1].time, t0);
    EXPECT_NE(journal_csv(rows).find("\"on my way, \"\"now\"\"\""), std::string::npos);
}

TEST(AlarmJournal, TheStatesOfTheLastRunAreTakenUpAtStart) {
    TempFile file("alarm-journal-restart");
    {
        auto journal = AlarmJournal::open(file.path);
        ASSERT_TRUE(journal) << journal.error().message;
        AlarmEngine engine({high_limit("temperature", 250)}, {"oven"});
        (*journal)->append(engine.feed("oven", "temperature", 260.0, "ok", "°C", t0));
        (*journal)->append(engine.acknowledge("oven.temperature_high", "ann", "", t0 + 1s).transitions);
        (*journal)->append(engine.shelve("oven.silent", 2h, "bob", "line work", t0 + 2s).transitions);
    }  // written as it closes
    auto journal = AlarmJournal::open(file.path);
    ASSERT_TRUE(journal) << journal.error().message;
    AlarmEngine engine({high_limit("temperature", 250)}, {"oven"});
    engine.restore((*journal)->last_states());
    const auto views = engine.views();
    const auto state = [&](const std::string& id) {
        for (const auto& view : views) {
            if (view.id == id) return view.state;
        }
        return AlarmState::normal;
    };
    EXPECT_EQ(state("oven.temperature_high"), AlarmState::active_acknowledged);
    EXPECT_EQ(state("oven.silent"), AlarmState::shelved);
    // Still high after the restart: no second raise.
    EXPECT_TRUE(engine.feed("oven", "temperature", 255.0, "ok", "°C", t0 + 1min).empty());
    // The shelving still ends when it was meant to.
    EXPECT_TRUE(engine.tick(t0 + 2h).empty());
    EXPECT_EQ(engine.tick(t0 + 2s + 2h).size(), 1U);
}

// An outage that raises a thousand alarms at once is one commit, and the file's history store
// writing beside it is not in the way.
TEST(AlarmJournal, AThousandTransitionsAreWrittenInOneTransaction) {
    TempFile file("alarm-journal-burst");
    HistoryOptions options;
    options.database = file.path;
    auto store = HistoryStore::open(options);
    ASSERT_TRUE(store) << store.error().message;
    auto journal = AlarmJournal::open(file.path);
    ASSERT_TRUE(journal) << journal.error().message;
    std::vector<std::string> devices;
    for (int i = 0; i < 1000; ++i) devices.push_back("device" + std::to_string(i));
    AlarmEngine engine({}, devices);
    Transitions burst;
    for (const auto& name : devices) {
        auto raised = engine.feed_device(name, device::DeviceStatus::no_reply, t0);
        burst.insert(burst.end(), raised.begin(), raised.end());
    }
    ASSERT_EQ(burst.size(), 1000U);
    (*journal)->append(burst);
    const auto started = std::chrono::steady_clock::now();
    ASSERT_TRUE((*journal)->write_pending());
    const auto took = std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now() - started);
    std::cout << "1000 alarm transitions written in " << took.count() << " us\n";
    EXPECT_EQ((*journal)->commits(), 1U);
    EXPECT_EQ((*journal)->rows_written(), 1000U);
    EXPECT_EQ(all_rows(file.path).size(), 1000U);
    ASSERT_TRUE((*store)->write_pending());  // the history's writer still writes the same file
}

}  // namespace
}  // namespace loopwire::gateway::alarms
