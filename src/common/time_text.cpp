#include "common/time_text.hpp"

#include <ctime>

#include <fmt/format.h>

namespace loopwire {
namespace {

// The calendar fields of `time` in UTC or the local zone, and its milliseconds.
struct CalendarTime {
    std::tm parts{};
    long long millis = 0;
};

CalendarTime calendar_time(std::chrono::system_clock::time_point time, bool utc) {
    using namespace std::chrono;
    const auto since_epoch = time.time_since_epoch();
    const auto whole = floor<seconds>(since_epoch);
    CalendarTime calendar;
    calendar.millis = duration_cast<milliseconds>(since_epoch - whole).count();
    const std::time_t seconds_count = static_cast<std::time_t>(whole.count());
    if (utc) {
        ::gmtime_r(&seconds_count, &calendar.parts);
    } else {
        ::localtime_r(&seconds_count, &calendar.parts);
    }
    return calendar;
}

// "2026-11-23T10:31:02.123", the part both forms share.
std::string date_and_time(const CalendarTime& calendar) {
    const std::tm& parts = calendar.parts;
    return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}", parts.tm_year + 1900, parts.tm_mon + 1, parts.tm_mday,
                       parts.tm_hour, parts.tm_min, parts.tm_sec, calendar.millis);
}

}  // namespace

std::string iso8601_utc(std::chrono::system_clock::time_point time) { return date_and_time(calendar_time(time, true)) + "Z"; }

std::string iso8601_local(std::chrono::system_clock::time_point time) {
    const CalendarTime calendar = calendar_time(time, false);
    const long offset_minutes = calendar.parts.tm_gmtoff / 60;
    const long magnitude = offset_minutes < 0 ? -offset_minutes : offset_minutes;
    return fmt::format("{}{}{:02}:{:02}", date_and_time(calendar), offset_minutes < 0 ? '-' : '+', magnitude / 60,
                       magnitude % 60);
}

std::string iso8601(std::chrono::system_clock::time_point time, bool utc) { return utc ? iso8601_utc(time) : iso8601_local(time); }

}  // namespace loopwire
