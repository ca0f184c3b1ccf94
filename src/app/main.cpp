// loopwire: read, write, simulate and explain Modbus traffic of process controllers.
#include <string>

#include <CLI/CLI.hpp>
#include <loopwire/version.hpp>

#include "app/commands.hpp"
#include "app/exit_codes.hpp"

int main(int argc, char** argv) {
    using namespace loopwire::app;
    CLI::App app{"loopwire: talk to, simulate and bridge process controllers over Modbus RTU, ASCII, TCP and Linking"};
    app.set_version_flag("--version", "loopwire " + std::string(loopwire::version()));
    app.require_subcommand(1);
    app.footer(exit_code_help);
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
    add_scan_command(app, exit_code);
    add_restore_command(app, exit_code, profiles);
    add_monitor_command(app, exit_code, profiles);
    add_dump_command(app, exit_code, profiles);
    add_gateway_command(app, exit_code, profiles);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& error) {
        const int printed = app.exit(error);
        return printed == 0 ? exit_ok : exit_usage;
    }
    return exit_code;
}
