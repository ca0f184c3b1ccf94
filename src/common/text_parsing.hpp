#pragma once
// The one parser for numbers and durations given as text (options, link URLs, files): strict,
// whole-string, and with errors that name the option and show the expected form, so a typo
// such as "1.2.3s" is a usage error where it was typed, not a link failure later.
#include <chrono>
#include <cstdint>
#include <optional>
#include <string_view>

#include "common/result.hpp"

namespace loopwire {

// "500ms", "2s", "1.5s", "1m" (or "1min"), "250us"; a bare number is milliseconds. Digits, at
// most one '.' followed by digits, then the unit: nothing else. `option` ("--timeout") names
// what is parsed in errors. A duration shorter than `least` is refused: pass 1ms for timeouts
// and intervals, where zero would mean "do not wait" or "spin" rather than anything useful.
Result<std::chrono::microseconds> parse_duration(std::string_view text, std::string_view option = "duration",
                                                 std::chrono::microseconds least = std::chrono::microseconds::zero());

// A span of days, for how long records are kept: "90d", "12h", "30m" (or "30min"), "3600s",
// a whole or decimal number ("1.5d") and its unit, which is required; at most 100 years, at
// least a second. `option` names it in errors, as for parse_duration.
Result<std::chrono::seconds> parse_period(std::string_view text, std::string_view option = "period");

// Decimal, 0x-prefixed hex or h-suffixed hex ("1Fh", as the manuals write); optionally signed.
Result<long long> parse_integer(std::string_view text, long long min, long long max, std::string_view what);

// Plain unsigned decimal digits making up the whole text (no sign, spaces, hex or overflow),
// for fields whose grammar is decimal only (link URL bauds, ports, bit counts).
std::optional<std::uint64_t> parse_decimal_digits(std::string_view text);

}  // namespace loopwire
