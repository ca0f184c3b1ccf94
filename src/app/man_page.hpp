#pragma once
// Man pages written from the command-line definitions themselves (the build runs
// `loopwire __man-pages`), so a page never says something the command does not do: loopwire.1
// and one loopwire-COMMAND.1 for each command, in roff (man(7)); and loopwire-gateway.toml.5,
// the gateway's configuration file, from its schema (gateway/config_schema.hpp).
#include <string>
#include <string_view>
#include <vector>

#include <CLI/CLI.hpp>

namespace loopwire::app {

struct ManPage {
    std::string file_name;  // loopwire.1, loopwire-read.1, ..., loopwire-gateway.toml.5: the last character is the section
    std::string text;
};

// `readme`: the text of README.md and docs/*.md; its `sh` examples of each command become the page's EXAMPLES
// (a block showing option synopses in [brackets] is not examples).
std::vector<ManPage> man_pages(const CLI::App& root, std::string_view version, std::string_view readme);

// `text` escaped for roff: backslashes, minus signs, characters beyond ASCII, and a leading
// dot or quote that would start a request.
std::string roff_escape(std::string_view text);

}  // namespace loopwire::app
