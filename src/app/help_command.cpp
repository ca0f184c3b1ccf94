// loopwire help [COMMAND]: the same text as `loopwire --help` or `loopwire COMMAND --help`.
#include <optional>

#include <fmt/format.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "profile/name_matching.hpp"

namespace loopwire::app {
namespace {

// The commands a user may type: the hidden ones (completion, man pages; no group) are for tools.
std::vector<std::string> command_names(const CLI::App& app) {
    std::vector<std::string> names;
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
        if (!sub->get_group().empty()) names.push_back(sub->get_name());
    }
    return names;
}

// The one command within two edits of `typed`, nearest first, if any.
std::optional<std::string> nearest_command(const CLI::App& app, const std::string& typed) {
    std::optional<std::string> nearest;
    std::size_t best = 3;
    for (const auto& name : command_names(app)) {
        const auto distance = device::edit_distance(typed, name);
        if (distance < best) {
            best = distance;
            nearest = name;
        }
    }
    return nearest;
}

int refuse_command(const CLI::App& app, const std::string& command) {
    if (const auto nearest = nearest_command(app, command)) {
        return report_error(make_error(ErrorKind::usage, fmt::format("there is no command '{}'; did you mean '{}'? "
                                                                     "(`loopwire --help` lists the commands)", command, *nearest)));
    }
    return report_error(make_error(ErrorKind::usage, fmt::format("there is no command '{}': choose one of {}", command,
                                                                 fmt::join(command_names(app), ", "))));
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
    return refuse_command(app, command);
}

}  // namespace

std::optional<int> refuse_unknown_command(const CLI::App& app, const std::string& first) {
    if (first.empty() || first.front() == '-') return std::nullopt;
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
        if (sub->check_name(first)) return std::nullopt;
    }
    return refuse_command(app, first);
}

void add_help_command(CLI::App& app, int& exit_code) {
    auto command_name = std::make_shared<std::string>();
    auto* command = app.add_subcommand("help", "Show the help of loopwire, or of one COMMAND (as `loopwire COMMAND --help`)");
    command->add_option("command", *command_name, "The command to explain");
    command->callback([&app, command_name, &exit_code] { exit_code = print_help(app, *command_name); });
}

}  // namespace loopwire::app
