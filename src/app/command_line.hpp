#pragma once
// Pieces every subcommand shares: parsing durations and numbers, the -v frame trace, and how
// errors are printed.
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "common/result.hpp"
#include "session/trace.hpp"

namespace loopwire::app {

// "500ms", "2s", "1.5s", "1m", "250us"; a bare number is milliseconds.
Result<std::chrono::microseconds> parse_duration(std::string_view text);

// Decimal, 0x-prefixed hex or h-suffixed hex ("1Fh", as the manuals write); optionally signed.
Result<long long> parse_integer(std::string_view text, long long min, long long max, std::string_view what);

// Prints each traced frame to stderr: "12:03:04.123456 TX 01 03 ...  note".
session::TraceSink stderr_trace();

// "loopwire: error: <message>" on stderr; returns the exit code for the error.
int report_error(const Error& error);

}  // namespace loopwire::app
