#include "app/scan_report.hpp"

#include <algorithm>
#include <cstdio>

#include <fmt/format.h>

namespace loopwire::app {

void ScanProgress::show(const std::string& line, int unit, std::size_t index, std::size_t total, std::size_t found) {
    if (!enabled_) return;
    fmt::print(stderr, "\r  {}: unit {:>3} ({}/{}), {} found\x1b[K", line, unit, index, total, found);
    std::fflush(stderr);
    shown_ = true;
}

void ScanProgress::clear() {
    if (!enabled_ || !shown_) return;
    fmt::print(stderr, "\r\x1b[K");
    std::fflush(stderr);
    shown_ = false;
}

bool ignores_line_settings(const std::vector<std::vector<int>>& found_per_setting) {
    if (found_per_setting.size() < 2 || found_per_setting.front().empty()) return false;
    return std::all_of(found_per_setting.begin(), found_per_setting.end(),
                       [&](const std::vector<int>& found) { return found == found_per_setting.front(); });
}

}  // namespace loopwire::app
