#pragma once
// A gateway's [history] file opened for a command that reads it (`loopwire audit`, `loopwire
// alarms`): a path that is not a regular file is refused, named, before SQLite would create it.
#include <filesystem>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "common/result.hpp"
#include "gateway/history_schema.hpp"

namespace loopwire::app {

inline Result<gateway::sqlite::Connection> open_history_file(std::string_view command, const std::string& path) {
    std::error_code error;
    if (!std::filesystem::is_regular_file(path, error)) {
        return make_error(ErrorKind::usage,
                          fmt::format("{}: {} is not a history file (a gateway's [history] database)", command, path));
    }
    return gateway::history::open_for_reading(path);
}

}  // namespace loopwire::app
