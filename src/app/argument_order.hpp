#pragma once
// Options may come before the command's name as well as after it: `loopwire -v read ...` works
// like `loopwire read -v ...`. CLI11 lets a parent's options follow a subcommand (fallthrough),
// not a subcommand's options precede it; so the arguments are reordered before parsing.
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace loopwire::app {

// `arguments` without the program name. Options before the first word that names one of
// `app`'s subcommands, that `app` itself does not know but that subcommand does, are moved to
// just after the subcommand's name, each with its value when it takes one ("--timeout 2s",
// "--timeout=2s"). Everything else keeps its place, so what cannot be moved is reported by
// the parser as before.
std::vector<std::string> options_after_command(const CLI::App& app, const std::vector<std::string>& arguments);

}  // namespace loopwire::app
