#pragma once
// Timestamps as monitor rows and dump documents carry them.
#include <chrono>
#include <string>

namespace loopwire {

// ISO 8601 in UTC with milliseconds: "2026-11-23T09:31:02.123Z".
std::string iso8601_utc(std::chrono::system_clock::time_point time);

// ISO 8601 in the local time zone (TZ) with its offset: "2026-11-23T10:31:02.123+01:00".
std::string iso8601_local(std::chrono::system_clock::time_point time);

// Either of the above.
std::string iso8601(std::chrono::system_clock::time_point time, bool utc);

}  // namespace loopwire
