#pragma once
// What `loopwire scan` tells while it runs: its progress on a terminal, and the warning that a
// line ignores the line settings swept over it.
#include <cstddef>
#include <string>
#include <vector>

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

// The units found at each line setting tried, in order. True when more than one setting was tried
// and every one found the same units, at least one: real devices answer at their own baud and
// parity only, so the same answers at every setting mean the line does not apply them (a
// pseudo-terminal, a TCP converter with fixed settings).
bool ignores_line_settings(const std::vector<std::vector<int>>& found_per_setting);

}  // namespace loopwire::app
