// Monitor logs that run unattended: format by extension, sizes, --append's header check, and
// rotation by size and by day fed with sample times chosen by the test (no waiting for midnight).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <unistd.h>

#include "client/monitor_file.hpp"
#include "client/monitor_records.hpp"
#include "client/monitor_state.hpp"
#include "client/read_report_of.hpp"
#include "common/time_text.hpp"

namespace loopwire::device {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

class MonitorFile : public ::testing::Test {
protected:
    void SetUp() override {
        folder_ = fs::temp_directory_path() / fs::path("loopwire-monitor-file-" + std::to_string(::getpid()) + "-" +
                                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(folder_);
        fs::create_directories(folder_);
    }
    void TearDown() override { fs::remove_all(folder_); }

    std::string path(const std::string& name) const { return (folder_ / name).string(); }

    std::vector<std::string> files() const {
        std::vector<std::string> names;
        for (const auto& entry : fs::directory_iterator(folder_)) names.push_back(entry.path().filename().string());
        std::sort(names.begin(), names.end());
        return names;
    }

    static std::string read(const std::string& file) {
        std::ifstream in(file);
        std::stringstream text;
        text << in.rdbuf();
        return text.str();
    }

    // Sample `index` at `time`, of no device (a CSV row is then "time,index").
    void write(FileSampleSink& sink, unsigned index, std::chrono::system_clock::time_point time) {
        sink.write(device::SampleView{index, time, device::MonitorClock::now(), &devices_});
    }

    fs::path folder_;
    std::vector<device::WatchedDevice> devices_;
};

// 2026-11-23T23:59:58Z.
const auto before_midnight = std::chrono::system_clock::time_point(std::chrono::seconds(1795478398));

TEST(MonitorFormatChoice, ExtensionChoosesUnlessFormatSaysOtherwise) {
    EXPECT_EQ(*choose_monitor_format("", "log.csv", false), MonitorFormat::csv);
    EXPECT_EQ(*choose_monitor_format("", "log.jsonl", false), MonitorFormat::jsonl);
    EXPECT_EQ(*choose_monitor_format("", "dir/log.NDJSON", false), MonitorFormat::jsonl);
    EXPECT_EQ(*choose_monitor_format("csv", "log.txt", false), MonitorFormat::csv);  // no opinion from .txt
    EXPECT_EQ(*choose_monitor_format("csv", "log.csv", false), MonitorFormat::csv);
    const auto conflict = choose_monitor_format("jsonl", "log.csv", false);
    ASSERT_FALSE(conflict);
    EXPECT_NE(conflict.error().message.find("--format jsonl contradicts --output log.csv"), std::string::npos);
    const auto unknown = choose_monitor_format("", "log.txt", false);
    ASSERT_FALSE(unknown);
    EXPECT_NE(unknown.error().message.find("add --format csv"), std::string::npos);
    EXPECT_FALSE(choose_monitor_format("table", "log.csv", false));
    EXPECT_EQ(*choose_monitor_format("", "", true), MonitorFormat::table);
    EXPECT_EQ(*choose_monitor_format("", "", false), MonitorFormat::jsonl);
}

TEST(MonitorByteSize, UnitsAndMistakes) {
    EXPECT_EQ(*parse_byte_size("10MB", "--rotate-size"), 10'000'000u);
    EXPECT_EQ(*parse_byte_size("500kB", "--rotate-size"), 500'000u);
    EXPECT_EQ(*parse_byte_size("2MiB", "--rotate-size"), 2u * 1024 * 1024);
    EXPECT_EQ(*parse_byte_size("65536", "--rotate-size"), 65536u);
    EXPECT_FALSE(parse_byte_size("10 MB", "--rotate-size"));
    EXPECT_FALSE(parse_byte_size("MB", "--rotate-size"));
    EXPECT_FALSE(parse_byte_size("99999999999999999999", "--rotate-size"));
    const auto tiny = parse_byte_size("999", "--rotate-size");
    ASSERT_FALSE(tiny);
    EXPECT_EQ(tiny.error().message, "--rotate-size '999' is too small: give at least 1kB (1000 bytes)");
    // The minimum it names is taken.
    EXPECT_EQ(*parse_byte_size("1kB", "--rotate-size"), 1000u);
}

TEST_F(MonitorFile, RotatesBySizeBeforeTheSampleThatWouldOverflowAndLosesNothing) {
    MonitorFileOptions options{path("log.csv"), false, std::uint64_t{1024}, false, TimeStyle::utc};
    auto sink = FileSampleSink::open(options, MonitorFormat::csv, "time,sample\n");
    ASSERT_TRUE(sink) << sink.error().message;
    for (unsigned i = 1; i <= 100; ++i) write(**sink, i, before_midnight + std::chrono::seconds(i));
    sink->reset();
    const auto names = files();
    ASSERT_GE(names.size(), 3u);
    // Rotated files carry the time of their first sample; the live one keeps the name.
    EXPECT_EQ(names.back(), "log.csv");
    EXPECT_EQ(names.front(), "log.2026-11-23T23-59-59.csv");
    std::vector<unsigned> samples;
    for (const auto& name : names) {
        const std::string text = read(path(name));
        EXPECT_LE(text.size(), 1024u) << name;
        std::istringstream lines(text);
        std::string line;
        std::getline(lines, line);
        EXPECT_EQ(line, "time,sample") << name;  // every file starts with the header
        while (std::getline(lines, line)) samples.push_back(static_cast<unsigned>(std::stoul(line.substr(line.find(',') + 1))));
    }
    // Rotated files sort by time before the live one: in that order, every sample once, in order.
    ASSERT_EQ(samples.size(), 100u);
    for (unsigned i = 0; i < 100; ++i) EXPECT_EQ(samples[i], i + 1);
}

TEST_F(MonitorFile, RotatesAtMidnightNamingTheFinishedFileByItsDay) {
    MonitorFileOptions options{path("log.jsonl"), false, std::nullopt, true, TimeStyle::utc};
    auto sink = FileSampleSink::open(options, MonitorFormat::jsonl, "");
    ASSERT_TRUE(sink) << sink.error().message;
    write(**sink, 1, before_midnight);
    write(**sink, 2, before_midnight + 1s);
    write(**sink, 3, before_midnight + 2s);  // 2026-11-24T00:00:00Z
    write(**sink, 4, before_midnight + 3s);
    sink->reset();
    EXPECT_EQ(files(), (std::vector<std::string>{"log.2026-11-23.jsonl", "log.jsonl"}));
    const std::string old_day = read(path("log.2026-11-23.jsonl"));
    const std::string new_day = read(path("log.jsonl"));
    EXPECT_NE(old_day.find("\"sample\":1"), std::string::npos);
    EXPECT_NE(old_day.find("\"time\":\"2026-11-23T23:59:59.000Z\",\"sample\":2"), std::string::npos);
    EXPECT_EQ(old_day.find("\"sample\":3"), std::string::npos);
    EXPECT_NE(new_day.find("\"time\":\"2026-11-24T00:00:00.000Z\",\"sample\":3"), std::string::npos);
    EXPECT_NE(new_day.find("\"sample\":4"), std::string::npos);
}

TEST_F(MonitorFile, AppendKeepsTheHeaderOnceAndRefusesAFileWithOtherColumns) {
    const std::string log = path("log.csv");
    MonitorFileOptions options{log, true, std::nullopt, false, TimeStyle::utc};
    for (unsigned run = 0; run < 2; ++run) {
        auto sink = FileSampleSink::open(options, MonitorFormat::csv, "time,sample\n");
        ASSERT_TRUE(sink) << sink.error().message;
        write(**sink, 1, before_midnight + std::chrono::seconds(run));
    }
    EXPECT_EQ(read(log), "time,sample\n2026-11-23T23:59:58.000Z,1\n2026-11-23T23:59:59.000Z,1\n");
    const auto other = FileSampleSink::open(options, MonitorFormat::csv, "time,sample,tc10@3 status\n");
    ASSERT_FALSE(other);
    EXPECT_NE(other.error().message.find("its CSV header differs"), std::string::npos) << other.error().message;
    EXPECT_NE(other.error().message.find("file:    time,sample\n"), std::string::npos) << other.error().message;
    EXPECT_EQ(read(log).size(), 66u);  // untouched
}

TEST_F(MonitorFile, AnEmptyFileAppendedToGetsTheHeader) {
    std::ofstream(path("log.csv")).flush();
    auto sink = FileSampleSink::open(MonitorFileOptions{path("log.csv"), true, std::nullopt, false, TimeStyle::utc},
                                     MonitorFormat::csv, "time,sample\n");
    ASSERT_TRUE(sink);
    write(**sink, 7, before_midnight);
    sink->reset();
    EXPECT_EQ(read(path("log.csv")), "time,sample\n2026-11-23T23:59:58.000Z,7\n");
}

TEST(MonitorCsv, SpecialStatesAreWrittenByName) {
    auto profile = device::builtin_profile("tc10");
    ASSERT_TRUE(profile);
    const auto* measured = (*profile)->find("measured_value");
    std::vector<device::WatchedDevice> devices{device::watch("tc10@3", {measured})};
    device::record_poll(devices[0], app::testing::report_of(**profile, {{"measured_value", 10000}}), true, {}, device::MonitorClock::now());
    const auto row = csv_row(device::SampleView{1, before_midnight, device::MonitorClock::now(), &devices});
    EXPECT_EQ(row, "2026-11-23T23:59:58.000Z,1,ok,0,out-of-range\n");
}

TEST(MonitorTime, LocalTimeCarriesItsOffset) {
    // POSIX TZ rules (no time zone database needed): CET is UTC+1, NST UTC-3:30.
    ::setenv("TZ", "CET-1", 1);
    ::tzset();
    EXPECT_EQ(iso8601(before_midnight, false), "2026-11-24T00:59:58.000+01:00");
    EXPECT_EQ(iso8601(before_midnight, true), "2026-11-23T23:59:58.000Z");
    ::setenv("TZ", "NST+3:30", 1);  // a half-hour offset, west of Greenwich
    ::tzset();
    EXPECT_EQ(iso8601(before_midnight, false), "2026-11-23T20:29:58.000-03:30");
    ::unsetenv("TZ");
    ::tzset();
}

}  // namespace
}  // namespace loopwire::device
