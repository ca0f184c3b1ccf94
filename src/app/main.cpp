// loopwire: read, write, simulate and explain Modbus traffic of process controllers.
#include <algorithm>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <loopwire/version.hpp>

#include "app/argument_order.hpp"
#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "app/json_errors.hpp"

int main(int argc, char** argv) {
    using namespace loopwire::app;
    CLI::App app{"loopwire: talk to, simulate and bridge process controllers over Modbus RTU, ASCII, TCP and Linking"};
    app.set_version_flag("--version", "loopwire " + std::string(loopwire::version()));
    app.require_subcommand(1);
    app.footer(std::string("Options may come before or after the command's name: `loopwire -v read ...` is `loopwire read -v ...`. "
                           "`loopwire help COMMAND` shows a command's options.\n\n") + exit_code_help);
    int exit_code = exit_ok;
    // Before the subcommands, which inherit the fallthrough that lets --profile follow them.
    ProfileOptions profiles;
    profiles.add_to(app);
    add_hidden_commands(app, exit_code);  // completion and man pages, from the commands added below
    add_read_command(app, exit_code, profiles);
    add_write_command(app, exit_code, profiles);
    add_simulate_command(app, exit_code, profiles);
    add_decode_command(app, exit_code);
    add_demo_command(app, exit_code);
    add_profile_commands(app, exit_code, profiles);
    add_profile_group_command(app, exit_code);
    add_scan_command(app, exit_code);
    add_restore_command(app, exit_code, profiles);
    add_monitor_command(app, exit_code, profiles);
    add_dump_command(app, exit_code, profiles);
    add_gateway_command(app, exit_code, profiles);
    add_history_command(app, exit_code);
    add_audit_command(app, exit_code);
    add_passwd_command(app, exit_code);
    add_alarms_command(app, exit_code);
    add_help_command(app, exit_code);
    // As every other error the program reports (command_line.hpp, report_error).
    app.failure_message([](const CLI::App*, const CLI::Error& error) {
        return "loopwire: error: " + std::string(error.what()) + "\nRun with --help for more information.\n";
    });
    std::vector<std::string> arguments(argv + 1, argv + argc);
    try {
        // Options may also precede the command's name (`loopwire -v read ...`).
        // "loopwire reed": CLI11 would only say that a command is required.
        if (!arguments.empty()) {
            if (const auto refused = refuse_unknown_command(app, arguments.front())) return *refused;
        }
        arguments = options_after_command(app, arguments);
        std::vector<char*> reordered{argv[0]};
        for (auto& argument : arguments) reordered.push_back(argument.data());
        app.parse(static_cast<int>(reordered.size()), reordered.data());
    } catch (const CLI::ParseError& error) {
        // With --json a script reads stdout: a bad argument is a JSON document there too
        // (json_errors.hpp), as every later error of the command is.
        const bool json = std::find(arguments.begin(), arguments.end(), "--json") != arguments.end();
        if (error.get_exit_code() != 0 && json) {
            JsonErrors on(true);
            return report_error(loopwire::make_error(loopwire::ErrorKind::usage, error.what()));
        }
        const int printed = app.exit(error);
        return printed == 0 ? exit_ok : exit_usage;
    }
    return exit_code;
}
