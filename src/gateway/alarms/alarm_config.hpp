#pragma once
// [[alarms.limits]]: the limit alarms of the gateway's configuration, parsed and checked against
// the devices of its [[lines]] (each parameter known to the device's profile, a number, and
// polled). Called by gateway_config.cpp; every mistake is noted as "FILE:LINE: KEY.PATH: what".
#include <string>
#include <vector>

#include <toml++/toml.h>

#include "common/result.hpp"
#include "gateway/alarms/alarm_engine.hpp"

namespace loopwire::gateway {
struct LineConfig;
}

namespace loopwire::gateway::alarms {

std::vector<LimitAlarm> parse_alarm_limits(const toml::table& root, const std::string& source,
                                           const std::vector<LineConfig>& lines, std::vector<Error>& mistakes);

}  // namespace loopwire::gateway::alarms
