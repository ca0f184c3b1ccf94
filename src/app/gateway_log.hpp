#pragma once
// The gateway's log (spdlog): one line per event on stderr, with its time and level, or, run by
// systemd with stderr to the journal (JOURNAL_STREAM names stderr), with the level as the
// sd-daemon priority prefix ("<4>") that journald makes the entry's priority, where
// `journalctl -u loopwire-gateway -p warning` picks out what needs a person and `-p notice`
// also what has recovered.
#include <memory>
#include <string>
#include <string_view>

#include <spdlog/formatter.h>
#include <spdlog/logger.h>

#include "gateway/gateway_config.hpp"
#include "gateway/forwarding_unit.hpp"

namespace loopwire::app {

// What each line of the log says after the time and level: whose event it is.
inline constexpr std::string_view gateway_log_tag = "gateway: ";

std::shared_ptr<spdlog::logger> make_gateway_logger();
// The log's format: `journal`, priority prefixes and no time; else time and level words.
std::unique_ptr<spdlog::formatter> make_gateway_formatter(bool journal);
void set_log_level(spdlog::logger& logger, gateway::LogConfig::Level level);

// What the gateway's parts log (refusals, devices that stop or start answering, statistics),
// at info level; at warning level for a line that begins with gateway_warning_prefix, and at
// notice for one that begins with gateway_notice_prefix.
void log_event(spdlog::logger& logger, const std::string& line);

}  // namespace loopwire::app
