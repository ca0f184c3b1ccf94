#pragma once
// What `loopwire scan` tells while it runs: its progress on a terminal (the scan itself is
// client/scan.hpp).
#include <cstddef>
#include <string>

namespace loopwire::app {

// "  9600 8N1: unit  17 (17/247), 1 found" redrawn in place on stderr, when stderr is a terminal
// (a log or pipe gets nothing). clear() wipes it before a result is printed on the same screen.
class ScanProgress {
public:
    explicit ScanProgress(bool enabled) : enabled_(enabled) {}
    void show(const std::string& line, int unit, std::size_t index, std::size_t total, std::size_t found);
    void clear();

private:
    bool enabled_;
    bool shown_ = false;
};

}  // namespace loopwire::app
