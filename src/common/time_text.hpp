#pragma once
// Timestamps as monitor rows and dump documents carry them.
#include <chrono>
#include <string>

namespace loopwire {

// ISO 8601 in UTC with milliseconds: "2026-11-23T09:31:02.123Z".
std::string iso8601_utc(std::chrono::system_clock::time_point time);

}  // namespace loopwire
