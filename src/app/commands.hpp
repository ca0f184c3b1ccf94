#pragma once
// Each subcommand registers itself on the CLI11 app and, when chosen, stores its exit code.
#include <CLI/CLI.hpp>

namespace loopwire::app {

void add_read_command(CLI::App& app, int& exit_code);
void add_write_command(CLI::App& app, int& exit_code);
void add_simulate_command(CLI::App& app, int& exit_code);
void add_decode_command(CLI::App& app, int& exit_code);
void add_demo_command(CLI::App& app, int& exit_code);
void add_profile_commands(CLI::App& app, int& exit_code);  // devices, describe
void add_scan_command(CLI::App& app, int& exit_code);
void add_restore_command(CLI::App& app, int& exit_code);
void add_monitor_command(CLI::App& app, int& exit_code);
void add_dump_command(CLI::App& app, int& exit_code);

}  // namespace loopwire::app
