#include "app/gateway_log.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <charconv>
#include <cstdlib>
#include <string_view>

#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/stdout_sinks.h>

namespace loopwire::app {
namespace {

// The levels an operator filters on are syslog's (`journalctl -p`): warning (4) for what needs a
// person (a line down, a device silent or another than configured), notice (5) for its end (the
// line up again, the device answering again). spdlog has no notice level: a notice is logged at
// info, so that `level = "warning"` hides it as it hides info, and its text begins with
// gateway_notice_prefix, which the flags below turn into the level: the word "notice" on a
// terminal or in a file, priority 5 in the journal.
std::string_view payload_of(const spdlog::details::log_msg& msg) { return {msg.payload.data(), msg.payload.size()}; }

bool is_notice(const spdlog::details::log_msg& msg) {
    return msg.level == spdlog::level::info && payload_of(msg).starts_with(gateway::gateway_notice_prefix);
}

// The sd-daemon priorities (sd-daemon.h SD_ERR .. SD_DEBUG), as the journal orders them.
int priority_of(const spdlog::details::log_msg& msg) {
    switch (msg.level) {
        case spdlog::level::critical: return 2;
        case spdlog::level::err: return 3;
        case spdlog::level::warn: return 4;
        case spdlog::level::info: return is_notice(msg) ? 5 : 6;
        default: return 7;
    }
}

void append(spdlog::memory_buf_t& dest, std::string_view text) { dest.append(text.data(), text.data() + text.size()); }

// "%*": the level. On a terminal or in a file its word ("warning", "notice"). In the journal the
// sd-daemon prefix "<4>": journald takes it from the start of a line on the service's stderr as
// the entry's priority (SyslogLevelPrefix=, on by default, systemd.exec(5)), so that
// `journalctl -p notice` shows the recoveries and `-p warning` does not. Writing to stderr with
// the prefix, rather than to the journal's socket, keeps the log in order with anything else on
// stderr and lets a test read the priorities from a pipe.
class LevelFlag final : public spdlog::custom_flag_formatter {
public:
    explicit LevelFlag(bool journal) : journal_(journal) {}

    void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
        if (journal_) {
            append(dest, fmt::format("<{}>", priority_of(msg)));
        } else {
            const auto word = spdlog::level::to_string_view(msg.level);
            append(dest, is_notice(msg) ? std::string_view("notice") : std::string_view(word.data(), word.size()));
        }
    }
    std::unique_ptr<custom_flag_formatter> clone() const override { return std::make_unique<LevelFlag>(journal_); }

private:
    bool journal_;
};

// "%&": the event, without the notice mark. In the journal every further line of it begins with
// the priority again: journald makes each line an entry of its own.
class EventFlag final : public spdlog::custom_flag_formatter {
public:
    explicit EventFlag(bool journal) : journal_(journal) {}

    void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
        std::string_view text = payload_of(msg);
        if (is_notice(msg)) text.remove_prefix(gateway::gateway_notice_prefix.size());
        if (!journal_) {
            append(dest, text);
            return;
        }
        const std::string again = fmt::format("\n<{}>{}", priority_of(msg), gateway_log_tag);
        for (std::size_t end = text.find('\n'); end != std::string_view::npos; end = text.find('\n')) {
            append(dest, text.substr(0, end));
            append(dest, again);
            text.remove_prefix(end + 1);
        }
        append(dest, text);
    }
    std::unique_ptr<custom_flag_formatter> clone() const override { return std::make_unique<EventFlag>(journal_); }

private:
    bool journal_;
};

// systemd sets JOURNAL_STREAM ("DEVICE:INODE") for a service whose stderr or stdout goes to the
// journal. A program started from such a service with stderr elsewhere (a redirect to a file)
// inherits the variable, so it counts only when it names stderr itself (systemd.exec(5)).
bool stderr_is_journal() {
    const char* stream = std::getenv("JOURNAL_STREAM");
    if (stream == nullptr) return false;
    const std::string_view text(stream);
    const auto colon = text.find(':');
    if (colon == std::string_view::npos) return false;
    std::uint64_t device = 0;
    std::uint64_t inode = 0;
    const auto parsed_device = std::from_chars(text.data(), text.data() + colon, device);
    const auto parsed_inode = std::from_chars(text.data() + colon + 1, text.data() + text.size(), inode);
    if (parsed_device.ec != std::errc() || parsed_inode.ec != std::errc() || parsed_inode.ptr != text.data() + text.size()) {
        return false;
    }
    struct stat status {};
    return ::fstat(STDERR_FILENO, &status) == 0 && status.st_dev == device && status.st_ino == inode;
}

}  // namespace

std::unique_ptr<spdlog::formatter> make_gateway_formatter(bool journal) {
    auto formatter = std::make_unique<spdlog::pattern_formatter>(spdlog::pattern_time_type::utc);
    formatter->add_flag<LevelFlag>('*', journal).add_flag<EventFlag>('&', journal);
    // The journal keeps the time, the unit and the program's name. Elsewhere: ISO 8601 UTC time,
    // level, then the event, one line each, easy to grep and to parse.
    formatter->set_pattern(journal ? fmt::format("%*{}%&", gateway_log_tag)
                                   : fmt::format("%Y-%m-%dT%H:%M:%S.%eZ %* loopwire: {}%&", gateway_log_tag));
    return formatter;
}

std::shared_ptr<spdlog::logger> make_gateway_logger() {
    auto logger = std::make_shared<spdlog::logger>("gateway", std::make_shared<spdlog::sinks::stderr_sink_mt>());
    logger->set_formatter(make_gateway_formatter(stderr_is_journal()));
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
        // A notice keeps its prefix: the formatter makes it the level (make_gateway_formatter).
        logger.info(line);
    }
}

}  // namespace loopwire::app
