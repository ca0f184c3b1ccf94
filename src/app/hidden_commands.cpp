// Commands for the build and the shell, not for people (hidden from --help):
//   loopwire __complete -- WORDS...          what to offer for the last word (completion scripts)
//   loopwire __man-pages --output-dir DIR    DIR/man1/loopwire.1, loopwire-COMMAND.1 and
//                                            DIR/man5/loopwire-gateway.toml.5 (the build)
// Both read the other commands' definitions from the app when they run, after every command
// has been added, so new commands and options appear in completion and man pages by themselves.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <loopwire/version.hpp>

#include "app/command_line.hpp"
#include "app/commands.hpp"
#include "app/completion.hpp"
#include "app/exit_codes.hpp"
#include "app/man_page.hpp"

namespace loopwire::app {
namespace {

const CLI::App& root_of(const CLI::App& command) {
    const CLI::App* root = &command;
    while (root->get_parent() != nullptr) root = root->get_parent();
    return *root;
}

// First line "files" (complete file names) or "words"; then one candidate a line.
int run_complete(const CLI::App& root, const std::vector<std::string>& words) {
    const ProfileLoader load = [](const std::vector<std::string>& files) {
        ProfileOptions profiles;
        profiles.files = files;
        return profiles.load();
    };
    const Completion completion = complete_command_line(root, words, load);
    fmt::print("{}\n", completion.files ? "files" : "words");
    for (const auto& word : completion.words) fmt::print("{}\n", word);
    return exit_ok;
}

Result<std::string> read_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return make_error(ErrorKind::usage, fmt::format("cannot read '{}': give the Markdown files' paths with --readme", path));
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// The examples live in README.md and the pages of docs/: their texts are read as one, each file
// ending its own code blocks.
int run_man_pages(const CLI::App& root, const std::string& output_dir, const std::vector<std::string>& readme_paths) {
    std::string readme;
    for (const std::string& path : readme_paths) {
        auto text = read_text(path);
        if (!text) return report_error(text.error());
        readme += *text + "\n";
    }
    for (const ManPage& page : man_pages(root, loopwire::version(), readme)) {
        // man1/loopwire.1, man5/loopwire-gateway.toml.5: the layout of share/man.
        const auto folder = std::filesystem::path(output_dir) / (std::string("man") + page.file_name.back());
        std::error_code error;
        std::filesystem::create_directories(folder, error);
        if (error) return report_error(make_error(ErrorKind::usage, fmt::format("cannot create '{}': {}", folder.string(), error.message())));
        const auto path = folder / page.file_name;
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out << page.text;
        if (!out.flush()) return report_error(make_error(ErrorKind::usage, fmt::format("cannot write '{}'", path.string())));
    }
    return exit_ok;
}

}  // namespace

void add_hidden_commands(CLI::App& app, int& exit_code) {
    auto words = std::make_shared<std::vector<std::string>>();
    auto* complete = app.add_subcommand("__complete", "Shell completion: the candidates for the last of WORDS");
    complete->group("");
    complete->add_option("words", *words, "The words after `loopwire`, the one being completed last (after --)");
    complete->callback([words, complete, &exit_code] { exit_code = run_complete(root_of(*complete), *words); });

    struct ManOptions {
        std::string output_dir;
        std::vector<std::string> readme;
    };
    auto options = std::make_shared<ManOptions>();
    auto* man = app.add_subcommand("__man-pages", "Write man1/loopwire.1, man1/loopwire-COMMAND.1 for every command and man5/loopwire-gateway.toml.5");
    man->group("");
    man->add_option("--output-dir", options->output_dir, "Folder to write the pages to, in man1/ and man5/")->required();
    man->add_option("--readme", options->readme, "README.md and the docs/*.md pages, whose examples of each command go on its page");
    man->callback([options, man, &exit_code] { exit_code = run_man_pages(root_of(*man), options->output_dir, options->readme); });
}

}  // namespace loopwire::app
