// loopwire help [COMMAND]: the same text as `loopwire --help` or `loopwire COMMAND --help`.
#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"

namespace loopwire::app {
namespace {

std::vector<std::string> command_names(const CLI::App& app) {
    std::vector<std::string> names;
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) names.push_back(sub->get_name());
    return names;
}

int print_help(const CLI::App& app, const std::string& command) {
    if (command.empty()) {
        // app.help() would show the selected command's, this one's: format the program's own.
        fmt::print("{}", app.get_formatter()->make_help(&app, app.get_name(), CLI::AppFormatMode::Normal));
        return exit_ok;
    }
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
        // As CLI11 prints `loopwire COMMAND --help`: the program's name, then the command's.
        if (sub->check_name(command)) {
            fmt::print("{}", sub->help(app.get_name()));
            return exit_ok;
        }
    }
    return report_error(make_error(ErrorKind::usage, fmt::format("there is no command '{}': choose one of {}", command,
                                                                 fmt::join(command_names(app), ", "))));
}

}  // namespace

void add_help_command(CLI::App& app, int& exit_code) {
    auto command_name = std::make_shared<std::string>();
    auto* command = app.add_subcommand("help", "Show the help of loopwire, or of one COMMAND (as `loopwire COMMAND --help`)");
    command->add_option("command", *command_name, "The command to explain");
    command->callback([&app, command_name, &exit_code] { exit_code = print_help(app, *command_name); });
}

}  // namespace loopwire::app
