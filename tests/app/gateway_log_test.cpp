// The gateway's log levels as an operator filters on them (app/gateway_log.hpp): a line down, a
// device silent or another than configured is a warning; its end a notice. In the journal
// (sd-daemon priority prefixes) `journalctl -p notice` shows the notices and `-p warning` does
// not; elsewhere the level is a word.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include <spdlog/sinks/ostream_sink.h>

#include "app/gateway_log.hpp"

namespace loopwire::app {
namespace {

using ::testing::ElementsAre;
using ::testing::MatchesRegex;

// Logs each event of `events` as the gateway's parts hand them over (log_event), at `level`,
// and returns the lines written.
std::vector<std::string> logged(bool journal, const std::vector<std::string>& events,
                                 gateway::LogConfig::Level level = gateway::LogConfig::Level::info) {
    std::ostringstream out;
    spdlog::logger logger("gateway", std::make_shared<spdlog::sinks::ostream_sink_st>(out));
    logger.set_formatter(make_gateway_formatter(journal));
    set_log_level(logger, level);
    for (const std::string& event : events) log_event(logger, event);
    std::vector<std::string> lines;
    std::istringstream written(out.str());
    for (std::string line; std::getline(written, line);) lines.push_back(line);
    return lines;
}

const std::vector<std::string> outage = {
    "warning: line furnace (rtu:/dev/ttyUSB0) is down: no such port",
    "notice: line furnace (rtu:/dev/ttyUSB0) is up again after 3.0 s down (2 reopen attempts)",
    "warning: device oven (tc10@3) does not answer: timeout; polled again with back-off",
    "notice: device oven (tc10@3) answers again",
    "device kiln (rampsoak@5) answers",
};

TEST(GatewayLog, InTheJournalEachLineBeginsWithItsPriority) {
    EXPECT_THAT(logged(true, outage),
                ElementsAre("<4>gateway: line furnace (rtu:/dev/ttyUSB0) is down: no such port",
                            "<5>gateway: line furnace (rtu:/dev/ttyUSB0) is up again after 3.0 s down (2 reopen attempts)",
                            "<4>gateway: device oven (tc10@3) does not answer: timeout; polled again with back-off",
                            "<5>gateway: device oven (tc10@3) answers again",
                            "<6>gateway: device kiln (rampsoak@5) answers"));
}

// journald makes each line an entry: the lines of one event (a reload's list of mistakes) each
// keep its priority.
TEST(GatewayLog, EveryLineOfAnEventOfSeveralLinesKeepsItsPriority) {
    EXPECT_THAT(logged(true, {"warning: configuration not reloaded: plant.toml:4: a\nplant.toml:9: b\n2 mistakes in plant.toml"}),
                ElementsAre("<4>gateway: configuration not reloaded: plant.toml:4: a", "<4>gateway: plant.toml:9: b",
                            "<4>gateway: 2 mistakes in plant.toml"));
}

TEST(GatewayLog, OnATerminalTheLevelIsAWordAfterTheTime) {
    const auto lines = logged(false, outage);
    ASSERT_EQ(lines.size(), 5u);
    const std::string time = "[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}:[0-9]{2}\\.[0-9]{3}Z";
    EXPECT_THAT(lines[0], MatchesRegex(time + " warning loopwire: gateway: line furnace .* is down: no such port"));
    EXPECT_THAT(lines[1], MatchesRegex(time + " notice loopwire: gateway: line furnace .* is up again after .*"));
    EXPECT_THAT(lines[3], MatchesRegex(time + " notice loopwire: gateway: device oven \\(tc10@3\\) answers again"));
    EXPECT_THAT(lines[4], MatchesRegex(time + " info loopwire: gateway: device kiln \\(rampsoak@5\\) answers"));
}

// A notice ranks below a warning: `level = "warning"` leaves only the warnings.
TEST(GatewayLog, AtLevelWarningNoticesAreLeftOut) {
    EXPECT_THAT(logged(true, outage, gateway::LogConfig::Level::warning),
                ElementsAre("<4>gateway: line furnace (rtu:/dev/ttyUSB0) is down: no such port",
                            "<4>gateway: device oven (tc10@3) does not answer: timeout; polled again with back-off"));
}

}  // namespace
}  // namespace loopwire::app
