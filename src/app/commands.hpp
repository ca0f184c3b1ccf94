#pragma once
#include <optional>
#include <string>
// Each subcommand registers itself on the CLI11 app and, when chosen, stores its exit code.
// Those that take a device id look it up in the registry `profiles` loads (main owns it; it
// outlives the parse).
#include <CLI/CLI.hpp>

#include "app/profile_options.hpp"

namespace loopwire::app {

void add_read_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles);
void add_write_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles);
void add_simulate_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles);
void add_decode_command(CLI::App& app, int& exit_code);
void add_demo_command(CLI::App& app, int& exit_code);
void add_profile_commands(CLI::App& app, int& exit_code, const ProfileOptions& profiles);  // devices, describe
void add_profile_group_command(CLI::App& app, int& exit_code);  // profile from-points
void add_scan_command(CLI::App& app, int& exit_code);
void add_restore_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles);
void add_monitor_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles);
void add_dump_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles);
void add_gateway_command(CLI::App& app, int& exit_code, const ProfileOptions& profiles);
void add_history_command(CLI::App& app, int& exit_code);
void add_audit_command(CLI::App& app, int& exit_code);
void add_passwd_command(CLI::App& app, int& exit_code);  // users of the HTTP API
void add_alarms_command(CLI::App& app, int& exit_code);
void add_help_command(CLI::App& app, int& exit_code);  // help [COMMAND]: add it last, it lists the others
// When `first`, the first argument, is a word that names no command ("reed"): the error, with the
// nearest command when one is close ("did you mean 'read'?"), else the list. Nothing otherwise.
std::optional<int> refuse_unknown_command(const CLI::App& app, const std::string& first);
// __complete and __man-pages (hidden): they read the other commands' definitions when they run.
void add_hidden_commands(CLI::App& app, int& exit_code);

}  // namespace loopwire::app
