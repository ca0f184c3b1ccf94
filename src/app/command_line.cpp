#include "app/command_line.hpp"

#include <cstdio>
#include <ctime>
#include <mutex>

#include <fmt/format.h>

#include "app/exit_codes.hpp"
#include "app/json_errors.hpp"

namespace loopwire::app {

std::string trace_line(const device::TraceEvent& event) {
    const auto wall = std::chrono::system_clock::now();
    const auto seconds = std::chrono::system_clock::to_time_t(wall);
    const auto micros = std::chrono::duration_cast<std::chrono::microseconds>(wall.time_since_epoch()).count() % 1000000;
    std::tm local{};
    localtime_r(&seconds, &local);
    const char* tag = event.direction == device::TraceDirection::sent       ? "TX"
                      : event.direction == device::TraceDirection::received ? "RX"
                                                                             : "!!";
    return fmt::format("{:02}:{:02}:{:02}.{:06} {} {}  {}", local.tm_hour, local.tm_min, local.tm_sec, micros, tag,
                       to_hex(event.bytes), event.note);
}

device::TraceSink stderr_trace() {
    auto lock = std::make_shared<std::mutex>();
    return [lock](const device::TraceEvent& event) {
        const std::string line = trace_line(event);
        std::lock_guard guard(*lock);
        fmt::print(stderr, "{}\n", line);
    };
}

// With --json a failure is one JSON object on stdout and nothing else: the same words again on
// stderr made a terminal show every error twice.
int report_error(const Error& error) {
    if (json_errors_on()) {
        fmt::print("{}\n", error_json(error).dump());
        std::fflush(stdout);
    } else {
        fmt::print(stderr, "loopwire: error: {}\n", error.message);
    }
    return exit_code_for(error);
}

}  // namespace loopwire::app
