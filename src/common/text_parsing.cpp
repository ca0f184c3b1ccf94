#include "common/text_parsing.hpp"

#include <charconv>
#include <cmath>
#include <string>

#include <fmt/format.h>

namespace loopwire {

std::optional<std::uint64_t> parse_decimal_digits(std::string_view text) {
    if (text.empty() || text.front() < '0' || text.front() > '9') return std::nullopt;  // from_chars would take no sign, but be explicit
    std::uint64_t value = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value, 10);
    if (ec != std::errc() || end != text.data() + text.size()) return std::nullopt;
    return value;
}

Result<std::chrono::microseconds> parse_duration(std::string_view text, std::string_view option, std::chrono::microseconds least) {
    const auto bad = [&] {
        return make_error(ErrorKind::usage, fmt::format("{} '{}' is not a duration: write it like 500ms, 2s, 1.5s, 1m or 1h", option, text));
    };
    std::size_t whole_end = 0;
    while (whole_end < text.size() && text[whole_end] >= '0' && text[whole_end] <= '9') ++whole_end;
    std::size_t number_end = whole_end;
    if (number_end < text.size() && text[number_end] == '.') {
        ++number_end;
        while (number_end < text.size() && text[number_end] >= '0' && text[number_end] <= '9') ++number_end;
        if (number_end == whole_end + 1) return bad();  // "1." or "1.s": digits must follow the point
    }
    if (whole_end == 0) return bad();  // no leading digit: "", ".5s", "-1s", "fast"
    // Digits and one point are exactly what from_chars reads as a plain decimal, and it reads
    // them without the locale (a ',' locale never turns "1.5s" into 1 s).
    double number = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + number_end, number, std::chars_format::fixed);
    if (ec != std::errc() || end != text.data() + number_end) return bad();
    const std::string_view unit = text.substr(number_end);
    double scale = 0;
    if (unit.empty() || unit == "ms") scale = 1e3;
    else if (unit == "s") scale = 1e6;
    else if (unit == "us") scale = 1;
    else if (unit == "m" || unit == "min") scale = 60e6;
    else if (unit == "h") scale = 3600e6;  // poll intervals of a slow plant, and the day limit below
    else return bad();
    const double micros = number * scale;
    if (!std::isfinite(micros) || micros > 86400e6) {
        return make_error(ErrorKind::usage, fmt::format("{} '{}' is longer than a day; give at most 24h, e.g. 1440m", option, text));
    }
    const std::chrono::microseconds duration(std::llround(micros));
    if (duration < least) {
        const std::string shortest = least.count() % 1000 == 0 ? fmt::format("{}ms", least.count() / 1000)
                                                               : fmt::format("{}us", least.count());
        return make_error(ErrorKind::usage, fmt::format("{} '{}' is too short: give at least {}, written like 500ms, 2s, 1.5s, 1m or 1h",
                                                        option, text, shortest));
    }
    return duration;
}

Result<std::chrono::seconds> parse_period(std::string_view text, std::string_view option) {
    const auto bad = [&] {
        return make_error(ErrorKind::usage, fmt::format("{} '{}' is not a period: write it like 90d, 12h, 30m or 3600s", option, text));
    };
    std::size_t number_end = 0;
    while (number_end < text.size() && ((text[number_end] >= '0' && text[number_end] <= '9') || text[number_end] == '.')) ++number_end;
    if (number_end == 0 || text[0] == '.' || text[number_end - 1] == '.') return bad();
    double number = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + number_end, number, std::chars_format::fixed);
    if (ec != std::errc() || end != text.data() + number_end) return bad();  // also "1.2.3d"
    const std::string_view unit = text.substr(number_end);
    double scale = 0;
    if (unit == "s") scale = 1;
    else if (unit == "m" || unit == "min") scale = 60;
    else if (unit == "h") scale = 3600;
    else if (unit == "d") scale = 86400;
    else return bad();
    const double seconds = number * scale;
    constexpr double most = 100.0 * 366 * 86400;
    if (!std::isfinite(seconds) || seconds > most) {
        return make_error(ErrorKind::usage, fmt::format("{} '{}' is longer than 100 years; give e.g. 3650d", option, text));
    }
    if (seconds < 1) return make_error(ErrorKind::usage, fmt::format("{} '{}' is too short: give at least 1s", option, text));
    return std::chrono::seconds(std::llround(seconds));
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
    // A second sign after the first ("+-5", "0x-5") is not a number: from_chars would take it.
    const bool signed_twice = !digits.empty() && (digits[0] == '-' || digits[0] == '+');
    auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value, base);
    if (digits.empty() || signed_twice || ec != std::errc() || end != digits.data() + digits.size()) {
        return make_error(ErrorKind::usage, fmt::format("{} '{}' is not a number (decimal, 0x1F or 1Fh)", what, text));
    }
    if (negative) value = -value;
    if (value < min || value > max) {
        return make_error(ErrorKind::usage, fmt::format("{} {} is out of range {}..{}", what, text, min, max));
    }
    return value;
}

}  // namespace loopwire
