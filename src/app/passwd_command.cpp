// loopwire passwd FILE NAME --role ROLE [--token]
// Adds or changes a user of the gateway's HTTP API ([http] users_file, gateway/http_users.hpp):
// a person's password (asked twice without echo on a terminal; one line from stdin otherwise,
// for scripts), or with --token a machine's bearer token, made here and printed once. The file
// is rewritten whole (a crash leaves the old one or the new one), readable by its owner alone.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <memory>

#include <fmt/format.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/exit_codes.hpp"
#include "common/atomic_file.hpp"
#include "common/regular_file.hpp"
#include "gateway/http_users.hpp"

namespace loopwire::app {
namespace {

struct PasswdOptions {
    std::string file;
    std::string name;
    std::string role;
    bool token = false;
};

// One line of stdin without its end; none at end of input.
std::optional<std::string> read_line() {
    std::string line;
    if (!std::getline(std::cin, line)) return std::nullopt;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return line;
}

// A line typed on the terminal with its echo off (restored however the read ends).
std::optional<std::string> read_hidden(const std::string& prompt) {
    std::fputs(prompt.c_str(), stderr);
    std::fflush(stderr);
    termios saved{};
    const bool terminal = ::tcgetattr(STDIN_FILENO, &saved) == 0;
    if (terminal) {
        termios quiet = saved;
        quiet.c_lflag &= ~static_cast<tcflag_t>(ECHO);
        quiet.c_lflag |= ECHONL;
        ::tcsetattr(STDIN_FILENO, TCSAFLUSH, &quiet);
    }
    auto line = read_line();
    if (terminal) ::tcsetattr(STDIN_FILENO, TCSAFLUSH, &saved);
    return line;
}

Result<std::string> ask_password(const std::string& name) {
    if (::isatty(STDIN_FILENO) == 0) {
        auto line = read_line();
        if (!line || line->empty()) {
            return make_error(ErrorKind::usage, "passwd: expected the password on the first line of stdin");
        }
        return *line;
    }
    auto first = read_hidden(fmt::format("New password for {}: ", name));
    if (!first || first->empty()) return make_error(ErrorKind::usage, "passwd: no password given; nothing changed");
    auto second = read_hidden("Again: ");
    if (!second || *second != *first) {
        return make_error(ErrorKind::usage, "passwd: the two passwords differ; nothing changed");
    }
    return *first;
}

int run_passwd(const PasswdOptions& options) {
    const auto role = gateway::parse_role(options.role);
    if (!role) {
        return report_error(make_error(ErrorKind::usage, fmt::format("passwd: \"{}\" is not a role (viewer, operator or admin)",
                                                                     options.role)));
    }
    std::string existing;
    bool known = false;  // the user has a line already
    if (::access(options.file.c_str(), F_OK) == 0) {
        auto text = read_regular_file(options.file, 1024 * 1024);
        if (!text) return report_error(make_error(ErrorKind::usage, fmt::format("passwd: {}", text.error().message)));
        // A file with a line that is wrong would stay wrong: say where, rather than write it again.
        auto users = gateway::parse_users(*text, options.file);
        if (!users) {
            return report_error(make_error(ErrorKind::usage, fmt::format("passwd: {} (mend or remove that line first)",
                                                                         users.error().message)));
        }
        known = std::any_of(users->begin(), users->end(), [&](const auto& user) { return user.name == options.name; });
        existing = std::move(*text);
    }
    gateway::HttpUser user{options.name, *role, {}};
    std::string token;
    if (options.token) {
        token = gateway::new_machine_token();
        user.hash = gateway::machine_token_hash(token);
    } else {
        auto password = ask_password(options.name);
        if (!password) return report_error(password.error());
        auto hash = gateway::hash_password(*password);
        if (!hash) return report_error(hash.error());
        user.hash = std::move(*hash);
    }
    // The line must read back: a name the file would refuse is refused here.
    const std::string text = gateway::users_text_with(existing, user);
    if (auto check = gateway::parse_users(text, options.file); !check) {
        return report_error(make_error(ErrorKind::usage, fmt::format("passwd: \"{}\" is not a user name (1 to 64 of A-Z a-z "
                                                                     "0-9 . _ @ -)", options.name)));
    }
    if (auto written = write_file_atomically(options.file, text, private_file_mode); !written) {
        return report_error(written.error());
    }
    ::chmod(options.file.c_str(), private_file_mode);  // an existing file keeps its mode otherwise
    if (options.token) {
        fmt::print("{}\n", token);
        fmt::print(stderr, "The token of {} ({}) is above; it is shown only now. Send it as \"Authorization: Bearer TOKEN\".\n",
                   options.name, options.role);
    } else {
        fmt::print(stderr, "{} {} ({}) in {}\n", known ? "Changed" : "Added", options.name, options.role, options.file);
    }
    return exit_ok;
}

}  // namespace

void add_passwd_command(CLI::App& app, int& exit_code) {
    auto options = std::make_shared<PasswdOptions>();
    auto* command = app.add_subcommand("passwd", "Add or change a user of the gateway's HTTP API in its [http] users_file");
    command->add_option("file", options->file, "The users file (created when absent, mode 0600)")->type_name("FILE")->required();
    command->add_option("name", options->name, "The user's name")->type_name("NAME")->required();
    command->add_option("--role", options->role,
                        "viewer (reads), operator (writes set points and modes), admin (writes every parameter)")
        ->type_name("ROLE")
        ->check(CLI::IsMember({"viewer", "operator", "admin"}))
        ->required();
    command->add_flag("--token", options->token,
                      "Make a bearer token for a machine instead of asking a password; the token is printed once on stdout");
    command->footer(std::string("The password is asked twice without echo; when stdin is not a terminal its first line is "
                                "the password (for scripts).\n\n") +
                    exit_code_help);
    command->callback([options, &exit_code] { exit_code = run_passwd(*options); });
}

}  // namespace loopwire::app
