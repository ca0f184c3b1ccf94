#include "app/command_line.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <mutex>

#include <fmt/format.h>

#include "app/exit_codes.hpp"

namespace loopwire::app {

Result<std::chrono::microseconds> parse_duration(std::string_view text) {
    const auto bad = [&] {
        return make_error(ErrorKind::usage, fmt::format("'{}' is not a duration: write it like 500ms, 2s, 1.5s or 1m", text));
    };
    std::size_t split = 0;
    while (split < text.size() && (std::isdigit(static_cast<unsigned char>(text[split])) || text[split] == '.')) ++split;
    if (split == 0) return bad();
    double number = 0;
    try {
        number = std::stod(std::string(text.substr(0, split)));
    } catch (...) {
        return bad();
    }
    const std::string_view unit = text.substr(split);
    double scale = 0;
    if (unit.empty() || unit == "ms") scale = 1e3;
    else if (unit == "s") scale = 1e6;
    else if (unit == "us") scale = 1;
    else if (unit == "m" || unit == "min") scale = 60e6;
    else return bad();
    const double micros = number * scale;
    if (!std::isfinite(micros) || micros > 86400e6) {
        return make_error(ErrorKind::usage, fmt::format("duration '{}' is longer than a day", text));
    }
    return std::chrono::microseconds(static_cast<long long>(micros));
}

Result<long long> parse_integer(std::string_view text, long long min, long long max, std::string_view what) {
    std::string_view digits = text;
    bool negative = false;
    if (!digits.empty() && (digits[0] == '-' || digits[0] == '+')) {
        negative = digits[0] == '-';
        digits.remove_prefix(1);
    }
    int base = 10;
    if (digits.size() > 2 && digits[0] == '0' && (digits[1] == 'x' || digits[1] == 'X')) {
        digits.remove_prefix(2);
        base = 16;
    } else if (digits.size() > 1 && (digits.back() == 'h' || digits.back() == 'H')) {
        digits.remove_suffix(1);
        base = 16;
    }
    long long value = 0;
    auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value, base);
    if (digits.empty() || ec != std::errc() || end != digits.data() + digits.size()) {
        return make_error(ErrorKind::usage, fmt::format("{} '{}' is not a number (decimal, 0x1F or 1Fh)", what, text));
    }
    if (negative) value = -value;
    if (value < min || value > max) {
        return make_error(ErrorKind::usage, fmt::format("{} {} is out of range {}..{}", what, text, min, max));
    }
    return value;
}

session::TraceSink stderr_trace() {
    auto lock = std::make_shared<std::mutex>();
    return [lock](const session::TraceEvent& event) {
        const auto wall = std::chrono::system_clock::now();
        const auto seconds = std::chrono::system_clock::to_time_t(wall);
        const auto micros = std::chrono::duration_cast<std::chrono::microseconds>(wall.time_since_epoch()).count() % 1000000;
        std::tm local{};
        localtime_r(&seconds, &local);
        const char* tag = event.direction == session::TraceDirection::sent       ? "TX"
                          : event.direction == session::TraceDirection::received ? "RX"
                                                                                 : "!!";
        std::lock_guard guard(*lock);
        fmt::print(stderr, "{:02}:{:02}:{:02}.{:06} {} {}  {}\n", local.tm_hour, local.tm_min, local.tm_sec, micros,
                   tag, to_hex(event.bytes), event.note);
    };
}

int report_error(const Error& error) {
    fmt::print(stderr, "loopwire: error: {}\n", error.message);
    return exit_code_for(error);
}

}  // namespace loopwire::app
