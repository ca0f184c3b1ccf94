#pragma once
// The gateway's log (spdlog): one line per event with its time and level on stderr, or, run by
// systemd (JOURNAL_STREAM set), straight to the journal with the level as the entry's priority,
// where `journalctl -u loopwire-gateway -p warning` can pick out what needs a person.
#include <memory>
#include <string>

#include <spdlog/logger.h>

#include "gateway/gateway_config.hpp"
#include "gateway/forwarding_unit.hpp"

namespace loopwire::app {

std::shared_ptr<spdlog::logger> make_gateway_logger();
void set_log_level(spdlog::logger& logger, gateway::LogConfig::Level level);

// What the gateway's parts log (refusals, devices that stop or start answering, statistics),
// at info level, or at warning level for a line that begins with gateway_warning_prefix.
void log_event(spdlog::logger& logger, const std::string& line);

}  // namespace loopwire::app
