// CLI conventions: options before the command's name, and the monitor table fitted to the
// terminal with traces above it.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>

#include <CLI/CLI.hpp>

#include "app/argument_order.hpp"
#include "app/monitor_screen.hpp"

namespace loopwire::app {
namespace {

struct TwoCommands {
    CLI::App app{"test"};
    bool verbose = false;
    std::string link, timeout, profile;
    std::vector<std::string> rest;
    TwoCommands() {
        app.add_option("--profile", profile);
        auto* read = app.add_subcommand("read");
        read->add_flag("-v,--verbose", verbose);
        read->add_option("--link", link);
        read->add_option("--timeout", timeout);
        read->add_option("rest", rest);
        app.add_subcommand("decode")->add_option("rest", rest);
    }
};

std::vector<std::string> words(std::initializer_list<const char*> list) { return {list.begin(), list.end()}; }

TEST(OptionsBeforeTheCommand, MoveAfterItsNameWithTheirValues) {
    TwoCommands cli;
    EXPECT_EQ(options_after_command(cli.app, words({"-v", "read", "holding", "0"})), words({"read", "-v", "holding", "0"}));
    EXPECT_EQ(options_after_command(cli.app, words({"--timeout", "2s", "-v", "read", "holding"})),
              words({"read", "--timeout", "2s", "-v", "holding"}));
    EXPECT_EQ(options_after_command(cli.app, words({"--link=tcp://h:502", "read", "x"})), words({"read", "--link=tcp://h:502", "x"}));
    // The program's own options stay where they are.
    EXPECT_EQ(options_after_command(cli.app, words({"--profile", "p.json", "-v", "read"})), words({"--profile", "p.json", "read", "-v"}));
    // Already after it, or an option the command does not know: unchanged (the parser says what is wrong).
    EXPECT_EQ(options_after_command(cli.app, words({"read", "-v"})), words({"read", "-v"}));
    EXPECT_EQ(options_after_command(cli.app, words({"-v", "decode", "01"})), words({"-v", "decode", "01"}));
}

TEST(OptionsBeforeTheCommand, ParseLikeOptionsAfterIt) {
    TwoCommands cli;
    auto arguments = options_after_command(cli.app, words({"-v", "--timeout", "2s", "read", "holding"}));
    std::vector<char*> argv{const_cast<char*>("loopwire")};
    for (auto& argument : arguments) argv.push_back(argument.data());
    cli.app.parse(static_cast<int>(argv.size()), argv.data());
    EXPECT_TRUE(cli.verbose);
    EXPECT_EQ(cli.timeout, "2s");
    EXPECT_EQ(cli.rest, words({"holding"}));
}

TEST(TableOnTheTerminal, LinesCutToTheWidthKeepingEscapesAndCharacters) {
    const std::vector<std::string> lines{"short", "\x1b[1m" "0123456789" "\x1b[0m", "°C°C°C°C°C°C"};
    const auto fitted = fit_to_screen(lines, TerminalSize{9, 24});
    EXPECT_EQ(fitted[0], "short");
    EXPECT_EQ(fitted[1], "\x1b[1m" "01234567" "\x1b[0m");  // 8 columns, attributes reset
    EXPECT_EQ(visible_width(fitted[1]), 8u);
    EXPECT_EQ(fitted[2], "°C°C°C°C\x1b[0m");
    EXPECT_EQ(visible_width(fitted[2]), 8u);
}

TEST(TableOnTheTerminal, TallerThanTheWindowEndsWithWhatDidNotFit) {
    std::vector<std::string> lines;
    for (int i = 0; i < 30; ++i) lines.push_back("line " + std::to_string(i));
    const auto fitted = fit_to_screen(lines, TerminalSize{80, 10});
    ASSERT_EQ(fitted.size(), 9u);  // the frame's last newline must not scroll the window
    EXPECT_EQ(fitted[7], "line 7");
    EXPECT_EQ(fitted[8], "... 22 more lines (a taller window, or fewer names, shows them)");
    EXPECT_EQ(fit_to_screen(lines, TerminalSize{80, 40}).size(), 30u);
}

TEST(TableOnTheTerminal, ParameterColumnGivesWayOnNarrowTerminals) {
    EXPECT_EQ(parameter_column_width(200), 34u);
    EXPECT_EQ(parameter_column_width(80), 31u);  // 2 + 31 + 47 = 80 columns, the last one left free
    EXPECT_EQ(parameter_column_width(40), 12u);
}

TEST(TableOnTheTerminal, TracesGoAboveTheTableWhichIsRedrawnUnderThem) {
    char* buffer = nullptr;
    std::size_t size = 0;
    std::FILE* out = ::open_memstream(&buffer, &size);
    {
        TableScreen screen(out);
        screen.draw({"title", "row"});
        screen.trace("12:00:00.000000 TX 01 03");
        screen.draw({"title", "row2"});
    }
    std::fclose(out);
    const std::string text(buffer, size);
    std::free(buffer);
    // The trace erases the 2 table lines, prints itself, then the table again below it.
    const auto trace_at = text.find("\x1b[2F\x1b[J\r12:00:00.000000 TX 01 03\x1b[K\n\rtitle\x1b[K\n\rrow\x1b[K\n");
    EXPECT_NE(trace_at, std::string::npos) << text;
    // The next frame overwrites only the table, leaving the trace above it.
    EXPECT_NE(text.find("\x1b[2F\rtitle\x1b[K\n\rrow2\x1b[K\n", trace_at), std::string::npos) << text;
    EXPECT_NE(text.find("\x1b[?25h"), std::string::npos);  // cursor shown at the end
}

}  // namespace
}  // namespace loopwire::app
