#include "app/gateway_log.hpp"

#include <cstdlib>

#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/sinks/systemd_sink.h>

namespace loopwire::app {

std::shared_ptr<spdlog::logger> make_gateway_logger() {
    if (std::getenv("JOURNAL_STREAM") != nullptr) {
        // The journal keeps the time and the unit; the identifier names the program.
        auto journal = std::make_shared<spdlog::sinks::systemd_sink_mt>("loopwire", true);
        auto logger = std::make_shared<spdlog::logger>("gateway", std::move(journal));
        logger->set_pattern("gateway: %v");
        return logger;
    }
    auto logger = std::make_shared<spdlog::logger>("gateway", std::make_shared<spdlog::sinks::stderr_sink_mt>());
    // ISO 8601 UTC time, level, then the event: one line each, easy to grep and to parse.
    logger->set_pattern("%Y-%m-%dT%H:%M:%S.%eZ %l loopwire: gateway: %v", spdlog::pattern_time_type::utc);
    logger->flush_on(spdlog::level::trace);  // a log read live (tail -f, tests) sees each line at once
    return logger;
}

void set_log_level(spdlog::logger& logger, gateway::LogConfig::Level level) {
    switch (level) {
        case gateway::LogConfig::Level::debug: logger.set_level(spdlog::level::debug); return;
        case gateway::LogConfig::Level::info: logger.set_level(spdlog::level::info); return;
        case gateway::LogConfig::Level::warning: logger.set_level(spdlog::level::warn); return;
        case gateway::LogConfig::Level::error: logger.set_level(spdlog::level::err); return;
    }
}

void log_event(spdlog::logger& logger, const std::string& line) {
    if (line.starts_with(gateway::gateway_warning_prefix)) {
        logger.warn(std::string_view(line).substr(gateway::gateway_warning_prefix.size()));
    } else {
        logger.info(line);
    }
}


}  // namespace loopwire::app
