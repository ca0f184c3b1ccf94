#pragma once
// Pieces every subcommand shares: the -v frame trace and how errors are printed. Numbers and
// durations are parsed by common/text_parsing.hpp, included here for every subcommand.
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "client/link.hpp"
#include "common/result.hpp"
#include "common/text_parsing.hpp"

namespace loopwire::app {

// One traced frame as a line (no newline): "12:03:04.123456 TX 01 03 ...  note".
std::string trace_line(const device::TraceEvent& event);

// Prints each traced frame to stderr as trace_line does.
device::TraceSink stderr_trace();

// "loopwire: error: <message>" on stderr; returns the exit code for the error.
int report_error(const Error& error);

}  // namespace loopwire::app
