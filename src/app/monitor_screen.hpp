#pragma once
// The live monitor table on a terminal: sized to the terminal's width and height, so it never
// wraps or scrolls (either would leave copies of its header on screen), and sharing the screen
// with -v traces. Traces are printed above the table, which is then redrawn under them: the
// frames scroll by like any log, the table stays whole at the bottom. (Traces printed straight
// to stderr would land in the middle of the table and be overwritten by the next frame.)
#include <cstddef>
#include <cstdio>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "app/monitor_output.hpp"
#include "client/link.hpp"

namespace loopwire::app {

struct TerminalSize {
    std::size_t columns = 80;
    std::size_t rows = 24;
};

// The size of the terminal on `fd` (TIOCGWINSZ), else COLUMNS and LINES, else 80 x 24.
TerminalSize terminal_size(int fd);

// Width of `text` on a terminal: escape sequences take none, a UTF-8 character one column.
std::size_t visible_width(std::string_view text);

// `lines` cut to fit: each to columns - 1 (the last column would wrap on some terminals),
// escape sequences kept whole and attributes reset after a cut; at most rows - 1 lines (the
// frame's last newline must not scroll), the last saying how many lines did not fit.
std::vector<std::string> fit_to_screen(std::vector<std::string> lines, TerminalSize size);

// The width of the table's PARAMETER column for a terminal this wide: the column gives way
// first (down to 12) so value, unit, status and age stay readable.
std::size_t parameter_column_width(std::size_t columns);

// The screen area below the traces: draw() replaces the table in place, trace() prints a line
// above it and redraws it. Both may be called from any thread.
class TableScreen {
public:
    explicit TableScreen(std::FILE* out) : out_(out) {}
    ~TableScreen();  // cursor shown, attributes reset
    TableScreen(const TableScreen&) = delete;
    TableScreen& operator=(const TableScreen&) = delete;

    void draw(std::vector<std::string> lines);
    void trace(const std::string& line);
    device::TraceSink trace_sink();

private:
    std::string render() const;

    std::mutex mutex_;
    std::FILE* out_;
    std::vector<std::string> lines_;
    std::size_t shown_ = 0;  // lines of the table on screen now
    bool started_ = false;
};

// Samples drawn as the table on a TableScreen, fitted to the terminal size at each sample (so
// resizing the window takes effect at the next one).
class TerminalTableSink final : public device::SampleSink {
public:
    TerminalTableSink(TableScreen& screen, int fd, TimeStyle time) : screen_(screen), fd_(fd), time_(time) {}
    void write(const device::SampleView& sample) override;

private:
    TableScreen& screen_;
    int fd_;
    TimeStyle time_;
};

}  // namespace loopwire::app
