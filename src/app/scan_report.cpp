#include "app/scan_report.hpp"

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

}  // namespace loopwire::app
