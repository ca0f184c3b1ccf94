// The pure pieces of `loopwire monitor`: back-off, per-device state, output formats, watch lists.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "client/monitor_backoff.hpp"
#include "client/monitor_names.hpp"
#include "app/monitor_output.hpp"
#include "client/monitor_state.hpp"
#include "common/time_text.hpp"
#include "client/read_report_of.hpp"

namespace loopwire::app {
namespace {

using namespace std::chrono_literals;

std::shared_ptr<const device::Profile> profile(const std::string& id) {
    auto loaded = device::builtin_profile(id);
    EXPECT_TRUE(loaded) << id;
    return *loaded;
}

using testing::report_of;

TEST(RetryBackoff, FirstRetryAfterOneWaitThenDoublesUpToTheCap) {
    device::RetryBackoff backoff(1000ms, 30000ms);
    const auto t0 = device::RetryBackoff::Clock::time_point{} + 1h;
    EXPECT_TRUE(backoff.due(t0));
    std::vector<long> waits;
    for (int failure = 0; failure < 8; ++failure) {
        backoff.failed(t0);
        waits.push_back(static_cast<long>(backoff.current_wait().count()));
    }
    EXPECT_EQ(waits, (std::vector<long>{1000, 2000, 4000, 8000, 16000, 30000, 30000, 30000}));
    EXPECT_EQ(backoff.consecutive_failures(), 8u);
}

TEST(RetryBackoff, NotDueUntilTheWaitHasPassedAndDueAgainAfterSuccess) {
    device::RetryBackoff backoff(200ms, 30000ms);
    const auto t0 = device::RetryBackoff::Clock::time_point{} + 1h;
    backoff.failed(t0);
    backoff.failed(t0);  // second failure: 400 ms
    EXPECT_FALSE(backoff.due(t0 + 399ms));
    EXPECT_TRUE(backoff.due(t0 + 400ms));
    backoff.succeeded();
    EXPECT_TRUE(backoff.due(t0));
    backoff.failed(t0);  // the doubling starts over after an answer
    EXPECT_EQ(backoff.current_wait(), 200ms);
}

TEST(MonitorState, AnsweredPollMakesValuesFreshAndMarksChangedRawWords) {
    auto p = profile("rampsoak");
    auto device = device::watch("rampsoak@5", {p->find("output_percentage"), p->find("controller_status")});
    const auto t0 = device::MonitorClock::now();
    device::record_poll(device, report_of(*p, {{"output_percentage", 125}, {"controller_status", 0}}), true, {}, t0);
    EXPECT_EQ(device.status, device::DeviceStatus::ok);
    EXPECT_TRUE(device.values[0].fresh);
    EXPECT_FALSE(device.values[0].changed);  // the first reading has nothing to differ from
    device::record_poll(device, report_of(*p, {{"output_percentage", 130}, {"controller_status", 0}}), true, {}, t0 + 1s);
    EXPECT_TRUE(device.values[0].changed);
    EXPECT_FALSE(device.values[1].changed);
    EXPECT_EQ(device.errors, 0u);
    EXPECT_EQ(device.polls, 2u);
}

TEST(MonitorState, UnansweredPollKeepsTheOldValueButNeverAsCurrent) {
    auto p = profile("rampsoak");
    auto device = device::watch("rampsoak@5", {p->find("output_percentage")});
    const auto t0 = device::MonitorClock::now();
    device::record_poll(device, report_of(*p, {{"output_percentage", 125}}), true, {}, t0);
    device::record_poll(device, device::ReadReport{}, false, "no reply from unit 5", t0 + 2s);
    EXPECT_EQ(device.status, device::DeviceStatus::no_reply);
    EXPECT_EQ(device.errors, 1u);
    EXPECT_FALSE(device.values[0].fresh);
    EXPECT_EQ(device::value_status(device, device.values[0]), "no-reply");
    EXPECT_NEAR(*device::age_seconds(device.values[0], t0 + 3s), 3.0, 1e-9);
    std::vector<device::WatchedDevice> devices{device};
    const auto row = sample_json(device::SampleView{2, std::chrono::system_clock::now(), t0 + 3s, &devices});
    const auto& entry = row["devices"]["rampsoak@5"]["values"]["output_percentage"];
    EXPECT_TRUE(entry["value"].is_null());
    EXPECT_TRUE(entry["text"].is_null());
    EXPECT_EQ(entry["status"], "no-reply");
    EXPECT_EQ(entry["age"], 3.0);
    device::record_skipped(devices[0]);
    EXPECT_EQ(device::value_status(devices[0], devices[0].values[0]), "waiting");
}

TEST(MonitorOutput, AUnitInBackOffSaysWhyAndWhenItIsTriedAgain) {
    auto p = profile("rampsoak");
    std::vector<device::WatchedDevice> devices{device::watch("rampsoak@5", {p->find("output_percentage")})};
    const auto t0 = device::MonitorClock::now();
    device::record_poll(devices[0], device::ReadReport{}, false, "no reply from unit 5", t0);
    devices[0].next_try = t0 + 2500ms;
    const auto row = sample_json(device::SampleView{1, std::chrono::system_clock::now(), t0 + 1s, &devices});
    EXPECT_EQ(row["devices"]["rampsoak@5"]["error"], "no reply from unit 5");
    EXPECT_EQ(row["devices"]["rampsoak@5"]["retry_in"], 1.5);
    const auto lines = table_lines(device::SampleView{1, std::chrono::system_clock::now(), t0 + 1s, &devices});
    EXPECT_EQ(lines[2], "rampsoak@5  no-reply  errors 1  retry in 1.5s  no reply from unit 5");
}

TEST(MonitorState, ValuesTheDeviceRefusedShowAsErrorsWhileTheRestIsCurrent) {
    auto p = profile("rampsoak");
    auto device = device::watch("rampsoak@5", {p->find("output_percentage"), p->find("controller_status")});
    auto report = report_of(*p, {{"output_percentage", 125}});
    report.readings.push_back(device::ParameterReading{p->find("controller_status"), std::nullopt, "exception 2"});
    report.first_error = make_error(ErrorKind::exception, "exception 2");
    device::record_poll(device, report, true, {}, device::MonitorClock::now());
    EXPECT_EQ(device.status, device::DeviceStatus::partial);
    EXPECT_EQ(device.errors, 1u);
    EXPECT_TRUE(device.values[0].fresh);
    EXPECT_EQ(device::value_status(device, device.values[1]), "error");
    EXPECT_EQ(device.values[1].error, "exception 2");
}

TEST(MonitorOutput, JsonLineCarriesIso8601UtcTimeAndEngineeringValues) {
    auto p = profile("rampsoak");
    std::vector<device::WatchedDevice> devices{device::watch("rampsoak@5", {p->find("output_percentage")})};
    const auto t0 = device::MonitorClock::now();
    device::record_poll(devices[0], report_of(*p, {{"output_percentage", 125}}), true, {}, t0);
    const auto time = std::chrono::system_clock::time_point(std::chrono::milliseconds(1795426262123));
    const auto row = sample_json(device::SampleView{1, time, t0, &devices});
    EXPECT_EQ(row["time"], "2026-11-23T09:31:02.123Z");
    EXPECT_EQ(row["sample"], 1);
    const auto& entry = row["devices"]["rampsoak@5"]["values"]["output_percentage"];
    EXPECT_EQ(entry["value"], 12.5);
    EXPECT_EQ(entry["text"], "12.5");
    EXPECT_EQ(entry["unit"], "%");
    EXPECT_EQ(entry["status"], "ok");
    EXPECT_EQ(entry["age"], 0.0);
}

TEST(MonitorOutput, CsvHasOneColumnPerDeviceValueAndLeavesUnreadCellsEmpty) {
    auto p = profile("rampsoak");
    std::vector<device::WatchedDevice> devices{device::watch("rampsoak@5", {p->find("output_percentage")}), device::watch("rampsoak@6", {p->find("output_percentage")})};
    const auto t0 = device::MonitorClock::now();
    device::record_poll(devices[0], report_of(*p, {{"output_percentage", 125}}), true, {}, t0);
    device::record_poll(devices[1], report_of(*p, {{"output_percentage", 300}}), true, {}, t0);
    device::record_poll(devices[1], device::ReadReport{}, false, "no reply", t0 + 1s);
    EXPECT_EQ(csv_header(devices),
              "time,sample,rampsoak@5 status,rampsoak@5 errors,rampsoak@5:output_percentage [%],"
              "rampsoak@6 status,rampsoak@6 errors,rampsoak@6:output_percentage [%]\n");
    const auto time = std::chrono::system_clock::time_point(std::chrono::milliseconds(1795426262000));
    EXPECT_EQ(csv_row(device::SampleView{3, time, t0 + 1s, &devices}), "2026-11-23T09:31:02.000Z,3,ok,0,12.5,no-reply,1,\n");
}

TEST(MonitorOutput, TableFramesHideTheCursorThenOverwriteThePreviousFrameInPlace) {
    const std::vector<std::string> lines{"a", "b", "c"};
    const auto first = table_frame(lines, 0);
    EXPECT_EQ(first.rfind("\x1b[?25l", 0), 0u);
    const auto next = table_frame(lines, 3);
    EXPECT_EQ(next.rfind("\x1b[3F", 0), 0u);  // back to the first line of the previous frame
    EXPECT_EQ(std::count(next.begin(), next.end(), '\n'), 3);
    EXPECT_NE(next.find("\rb\x1b[K\n"), std::string::npos);
    EXPECT_NE(std::string(terminal_restore).find("\x1b[?25h"), std::string::npos);
}

TEST(MonitorOutput, TableShowsChangedValuesBoldAndUnreadOnesDimWithTheirStatus) {
    auto p = profile("rampsoak");
    std::vector<device::WatchedDevice> devices{device::watch("rampsoak@5", {p->find("output_percentage")})};
    const auto t0 = device::MonitorClock::now();
    device::record_poll(devices[0], report_of(*p, {{"output_percentage", 125}}), true, {}, t0);
    device::record_poll(devices[0], report_of(*p, {{"output_percentage", 126}}), true, {}, t0);
    auto lines = table_lines(device::SampleView{2, std::chrono::system_clock::now(), t0, &devices});
    ASSERT_EQ(lines.size(), 4u);
    EXPECT_NE(lines[1].find("PARAMETER"), std::string::npos);
    EXPECT_NE(lines[2].find("rampsoak@5  ok  errors 0"), std::string::npos);
    EXPECT_NE(lines[3].find("\x1b[1m"), std::string::npos);
    EXPECT_NE(lines[3].find("12.6"), std::string::npos);
    device::record_poll(devices[0], device::ReadReport{}, false, "no reply", t0 + 5s);
    lines = table_lines(device::SampleView{3, std::chrono::system_clock::now(), t0 + 5s, &devices});
    EXPECT_NE(lines[3].find("\x1b[2m"), std::string::npos);
    EXPECT_NE(lines[3].find("no-reply"), std::string::npos);
    EXPECT_NE(lines[3].find("5.0s"), std::string::npos);
}

std::vector<device::DeviceAddress> devices_of(const std::vector<std::string>& texts) {
    std::vector<device::DeviceAddress> devices;
    for (const auto& text : texts) devices.push_back(*device::parse_device_address(text));
    return devices;
}

std::vector<std::string> names_of(const std::vector<const device::Parameter*>& list) {
    std::vector<std::string> names;
    for (const auto* p : list) names.push_back(p->name);
    return names;
}

// Monitor default watch lists: TC10 §5.1 words 1A/3A/4A/10A/15A and SP (717), ramp/soak §7 rows
// 008AH/0000H/0087H/0088H, AC20 words 123/125/138/137/130/135 — every listed name must exist and
// be readable, and each list holds the profile's PV, SP and OUT.
TEST(MonitorNames, DefaultWatchListsNameReadableParametersOfEveryBuiltInProfile) {
    const std::map<std::string, std::size_t> expected{{"tc10", 6}, {"rampsoak", 4}, {"ac20", 6}};
    for (const auto& id : device::builtin_profile_ids()) {
        const auto list = device::default_watch_list(*profile(id));
        EXPECT_EQ(list.size(), expected.at(id)) << id;
        for (const auto* p : list) EXPECT_TRUE(p->readable) << id << " " << p->name;
        for (const char* alias : {"PV", "SP", "OUT"}) {
            const auto* aliased = profile(id)->find(profile(id)->aliases.at(alias));
            EXPECT_NE(std::find(list.begin(), list.end(), aliased), list.end()) << id << " watches no " << alias;
        }
    }
    EXPECT_EQ(names_of(device::default_watch_list(*profile("tc10"))),
              (std::vector<std::string>{"measured_value", "set_point", "operating_set_point", "output_power", "alarm_status",
                                        "control_state"}));
}

TEST(MonitorNames, PlainNameAppliesToEveryDevice) {
    const auto devices = devices_of({"tc10@3", "rampsoak@5"});
    auto lists = device::watch_lists(devices, {"OUT"});
    ASSERT_TRUE(lists) << lists.error().message;
    EXPECT_EQ(names_of((*lists)[0]), (std::vector<std::string>{"output_power"}));
    EXPECT_EQ(names_of((*lists)[1]), (std::vector<std::string>{"output_percentage"}));
}

// A name that matches nothing on one of the devices is an error naming that device, not a
// silently shorter watch list there.
TEST(MonitorNames, PlainNameMissingOnOneDeviceIsAnErrorNamingIt) {
    const auto devices = devices_of({"tc10@3", "rampsoak@5"});
    auto lists = device::watch_lists(devices, {"output_power"});
    ASSERT_FALSE(lists);
    EXPECT_EQ(lists.error().kind, ErrorKind::usage);
    EXPECT_NE(lists.error().message.find("rampsoak@5: no parameter \"output_power\" on rampsoak"), std::string::npos)
        << lists.error().message;
    EXPECT_NE(lists.error().message.find("write tc10@3:output_power"), std::string::npos) << lists.error().message;
    auto qualified = device::watch_lists(devices, {"tc10@3:output_power"});
    ASSERT_TRUE(qualified) << qualified.error().message;
    EXPECT_EQ(names_of((*qualified)[0]), (std::vector<std::string>{"output_power"}));
    EXPECT_EQ(names_of((*qualified)[1]), names_of(device::default_watch_list(*devices[1].profile)));
}

TEST(MonitorNames, DeviceQualifiedNameAppliesToThatDeviceOnly) {
    const auto devices = devices_of({"tc10@3", "tc10@4"});
    auto lists = device::watch_lists(devices, {"tc10@4:SP.HL", "tc10@4:set_point"});
    ASSERT_TRUE(lists);
    EXPECT_EQ(names_of((*lists)[1]), (std::vector<std::string>{"set_point_high_limit", "set_point"}));
    EXPECT_EQ((*lists)[0].size(), 6u);  // defaults
}

TEST(MonitorNames, UnknownNamesAndDevicesAreUsageErrors) {
    const auto devices = devices_of({"tc10@3"});
    auto unknown = device::watch_lists(devices, {"nosuch"});
    ASSERT_FALSE(unknown);
    EXPECT_EQ(unknown.error().kind, ErrorKind::usage);
    auto other_device = device::watch_lists(devices, {"tc10@9:SP"});
    ASSERT_FALSE(other_device);
    EXPECT_NE(other_device.error().message.find("not one of the --device options"), std::string::npos);
}

}  // namespace
}  // namespace loopwire::app
