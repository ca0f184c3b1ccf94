#include "common/time_text.hpp"

#include <ctime>

#include <fmt/format.h>

namespace loopwire {

std::string iso8601_utc(std::chrono::system_clock::time_point time) {
    using namespace std::chrono;
    const auto since_epoch = time.time_since_epoch();
    const auto whole = floor<seconds>(since_epoch);
    const auto millis = duration_cast<milliseconds>(since_epoch - whole).count();
    const std::time_t seconds_count = static_cast<std::time_t>(whole.count());
    std::tm parts{};
    ::gmtime_r(&seconds_count, &parts);
    return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z", parts.tm_year + 1900, parts.tm_mon + 1, parts.tm_mday,
                       parts.tm_hour, parts.tm_min, parts.tm_sec, millis);
}

std::string iso8601_local(std::chrono::system_clock::time_point time) {
    using namespace std::chrono;
    const auto since_epoch = time.time_since_epoch();
    const auto whole = floor<seconds>(since_epoch);
    const auto millis = duration_cast<milliseconds>(since_epoch - whole).count();
    const std::time_t seconds_count = static_cast<std::time_t>(whole.count());
    std::tm parts{};
    ::localtime_r(&seconds_count, &parts);
    const long offset_minutes = parts.tm_gmtoff / 60;
    const long magnitude = offset_minutes < 0 ? -offset_minutes : offset_minutes;
    return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}{}{:02}:{:02}", parts.tm_year + 1900, parts.tm_mon + 1,
                       parts.tm_mday, parts.tm_hour, parts.tm_min, parts.tm_sec, millis, offset_minutes < 0 ? '-' : '+',
                       magnitude / 60, magnitude % 60);
}

std::string iso8601(std::chrono::system_clock::time_point time, bool utc) { return utc ? iso8601_utc(time) : iso8601_local(time); }

}  // namespace loopwire
