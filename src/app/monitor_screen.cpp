#include "app/monitor_screen.hpp"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>

#include <fmt/format.h>

#include "app/command_line.hpp"

namespace loopwire::app {
namespace {

std::size_t env_size(const char* name) {
    const char* text = std::getenv(name);
    if (text == nullptr) return 0;
    char* end = nullptr;
    const unsigned long value = std::strtoul(text, &end, 10);
    return end != text && *end == '\0' && value < 10000 ? static_cast<std::size_t>(value) : 0;
}

bool continuation_byte(char c) { return (static_cast<unsigned char>(c) & 0xC0) == 0x80; }

// Index just past the escape sequence starting at `at` ("\x1b[...X").
std::size_t skip_escape(std::string_view text, std::size_t at) {
    std::size_t i = at + 1;
    if (i < text.size() && text[i] == '[') {
        ++i;
        while (i < text.size() && !(text[i] >= '@' && text[i] <= '~')) ++i;
    }
    return std::min(i + 1, text.size());
}

// `text` cut to `width` visible columns.
std::string cut(std::string_view text, std::size_t width) {
    std::string out;
    std::size_t columns = 0;
    bool cut_short = false;
    for (std::size_t i = 0; i < text.size();) {
        if (text[i] == '\x1b') {
            const std::size_t end = skip_escape(text, i);
            out.append(text.substr(i, end - i));
            i = end;
            continue;
        }
        if (!continuation_byte(text[i])) {
            if (columns == width) {
                cut_short = true;
                break;
            }
            ++columns;
        }
        out += text[i++];
    }
    if (cut_short) out += "\x1b[0m";
    return out;
}

}  // namespace

TerminalSize terminal_size(int fd) {
    TerminalSize size;
    winsize window{};
    if (::ioctl(fd, TIOCGWINSZ, &window) == 0 && window.ws_col > 0 && window.ws_row > 0) {
        size.columns = window.ws_col;
        size.rows = window.ws_row;
        return size;
    }
    if (const auto columns = env_size("COLUMNS"); columns > 0) size.columns = columns;
    if (const auto rows = env_size("LINES"); rows > 0) size.rows = rows;
    return size;
}

std::size_t visible_width(std::string_view text) {
    std::size_t columns = 0;
    for (std::size_t i = 0; i < text.size();) {
        if (text[i] == '\x1b') {
            i = skip_escape(text, i);
            continue;
        }
        if (!continuation_byte(text[i])) ++columns;
        ++i;
    }
    return columns;
}

std::vector<std::string> fit_to_screen(std::vector<std::string> lines, TerminalSize size) {
    const std::size_t width = std::max<std::size_t>(size.columns, 2) - 1;
    const std::size_t height = std::max<std::size_t>(size.rows, 3) - 1;
    if (lines.size() > height) {
        const std::size_t hidden = lines.size() - (height - 1);
        lines.resize(height - 1);
        lines.push_back(fmt::format("... {} more line{} (a taller window, or fewer names, shows them)", hidden, hidden == 1 ? "" : "s"));
    }
    for (auto& line : lines) {
        if (visible_width(line) > width) line = cut(line, width);
    }
    return lines;
}

std::size_t parameter_column_width(std::size_t columns) {
    // "  " NAME " " VALUE(14) " " UNIT(6) " " STATUS(14) " " AGE(8), within columns - 1.
    constexpr std::size_t others = 2 + 1 + 14 + 1 + 6 + 1 + 14 + 1 + 8;
    const std::size_t usable = columns > others + 1 ? columns - 1 - others : 0;
    return std::clamp<std::size_t>(usable, 12, 34);
}

TableScreen::~TableScreen() {
    std::lock_guard lock(mutex_);
    if (!started_) return;
    std::fputs(terminal_restore, out_);
    std::fflush(out_);
}

std::string TableScreen::render() const {
    std::string text;
    for (const auto& line : lines_) text += "\r" + line + "\x1b[K\n";
    return text;
}

void TableScreen::draw(std::vector<std::string> lines) {
    std::lock_guard lock(mutex_);
    std::string text = started_ ? (shown_ > 0 ? fmt::format("\x1b[{}F", shown_) : std::string()) : std::string("\x1b[?25l");
    started_ = true;
    lines_ = std::move(lines);
    text += render() + "\x1b[J";  // a shorter table than the last leaves nothing of it below
    shown_ = lines_.size();
    std::fputs(text.c_str(), out_);
    std::fflush(out_);
}

void TableScreen::trace(const std::string& line) {
    std::lock_guard lock(mutex_);
    std::string text = shown_ > 0 ? fmt::format("\x1b[{}F\x1b[J", shown_) : std::string();
    text += "\r" + line + "\x1b[K\n" + render();
    std::fputs(text.c_str(), out_);
    std::fflush(out_);
}

device::TraceSink TableScreen::trace_sink() {
    return [this](const device::TraceEvent& event) { trace(trace_line(event)); };
}

void TerminalTableSink::write(const device::SampleView& sample) {
    const TerminalSize size = terminal_size(fd_);
    screen_.draw(fit_to_screen(table_lines(sample, time_, parameter_column_width(size.columns)), size));
}

}  // namespace loopwire::app
