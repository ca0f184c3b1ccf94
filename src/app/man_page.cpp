#include "app/man_page.hpp"

#include <algorithm>
#include <cctype>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "gateway/config_schema.hpp"

namespace loopwire::app {
namespace {

using Examples = std::map<std::string, std::vector<std::string>>;

constexpr std::string_view config_page_name = "loopwire-gateway.toml";

// The code point of the UTF-8 sequence starting at text[i]; `i` moves past it. A byte that does
// not start a valid sequence stands for itself.
char32_t next_code_point(std::string_view text, std::size_t& i) {
    const auto lead = static_cast<unsigned char>(text[i++]);
    const int more = lead >= 0xF0 ? 3 : lead >= 0xE0 ? 2 : lead >= 0xC0 ? 1 : 0;
    char32_t code = more == 0 ? lead : lead & (0x3Fu >> more);
    for (int k = 0; k < more && i < text.size(); ++k) code = (code << 6) | (static_cast<unsigned char>(text[i++]) & 0x3Fu);
    return code;
}

std::string upper(std::string_view text) {
    std::string out(text);
    std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
    return out;
}

std::string bold(std::string_view text) { return "\\fB" + roff_escape(text) + "\\fR"; }
std::string italic(std::string_view text) { return "\\fI" + roff_escape(text) + "\\fR"; }

// A help text as a sentence: escaped, ending with a full stop.
std::string sentence(std::string_view text) {
    std::string out = roff_escape(text);
    if (!out.empty() && out.back() != '.') out += '.';
    return out;
}

bool visible(const CLI::Option& option) { return !option.get_group().empty(); }

// What an option's value is called: the choices of a CLI::IsMember check ("rtu|ascii"), a type
// name the definition gives (FILE.json), else the option's own name (--link LINK).
std::string value_name(const CLI::Option& option) {
    const std::string type = option.get_type_name();
    const auto open = type.find('{');
    const auto close = type.find('}', open);
    if (open != std::string::npos && close != std::string::npos) {
        std::string choices = type.substr(open + 1, close - open - 1);
        std::replace(choices.begin(), choices.end(), ',', '|');
        return choices;
    }
    const std::string declared = type.substr(0, type.find(':'));
    static const char* const generic[] = {"", "TEXT", "INT", "UINT", "FLOAT", "NUMBER", "BOOLEAN", "ENUM", "INT in", "FLOAT in"};
    if (std::find(std::begin(generic), std::end(generic), declared) == std::end(generic)) return declared;
    std::string name = option.get_lnames().empty() ? option.get_single_name() : option.get_lnames().front();
    std::replace(name.begin(), name.end(), '-', '_');
    return upper(name);
}

bool repeatable(const CLI::Option& option) { return option.get_items_expected_max() > 1; }

// "\fB--link\fR \fILINK\fR" for an option, "\fIARGUMENTS\fR..." for a positional.
std::string option_usage(const CLI::Option& option, bool all_names) {
    if (option.get_positional()) return italic(upper(option.get_name(true))) + (repeatable(option) ? "..." : "");
    std::vector<std::string> names;
    for (const auto& name : option.get_snames()) names.push_back(bold("-" + name));
    for (const auto& name : option.get_lnames()) names.push_back(bold("--" + name));
    if (!all_names) names = {names.back()};
    std::string usage = fmt::format("{}", fmt::join(names, ", "));
    if (option.get_items_expected_max() > 0) usage += " " + italic(value_name(option));  // flags expect 0
    return usage;
}

std::vector<const CLI::Option*> shown_options(const CLI::App& command) {
    auto options = command.get_options([](const CLI::Option* option) { return visible(*option); });
    // Positionals last, as they are typed.
    std::stable_partition(options.begin(), options.end(), [](const CLI::Option* option) { return !option->get_positional(); });
    return options;
}

std::string synopsis(const std::string& program, const CLI::App& command, const CLI::App* root) {
    std::ostringstream out;
    out << ".SH SYNOPSIS\n.B " << roff_escape(program) << "\n";
    auto options = shown_options(command);
    if (root != nullptr) {  // options the command falls through to (--profile) are given after it too
        for (const CLI::Option* option : root->get_options()) {
            if (visible(*option) && option != root->get_help_ptr() && option != root->get_version_ptr()) options.insert(options.begin(), option);
        }
    }
    for (const CLI::Option* option : options) {
        if (option == command.get_help_ptr()) continue;
        const std::string usage = option_usage(*option, false);
        const std::string more = repeatable(*option) && !option->get_positional() ? "..." : "";
        out << (option->get_required() ? usage + more : "[" + usage + "]" + more) << "\n";
    }
    return out.str();
}

std::string option_item(const CLI::Option& option) {
    std::string text = sentence(option.get_description());
    if (!option.get_default_str().empty()) text += " Default: " + roff_escape(option.get_default_str()) + ".";
    if (option.get_required()) text += " Required.";
    if (repeatable(option) && !option.get_positional()) text += " May be given more than once.";
    return ".TP\n" + option_usage(option, true) + "\n" + text + "\n";
}

std::string options_section(const CLI::App& command, const CLI::App* root) {
    std::string out = ".SH OPTIONS\n";
    for (const CLI::Option* option : shown_options(command)) out += option_item(*option);
    if (root != nullptr) {
        for (const CLI::Option* option : root->get_options()) {
            if (visible(*option) && option != root->get_help_ptr() && option != root->get_version_ptr()) out += option_item(*option);
        }
    }
    return out;
}

// A footer "Exit status:\n  0  success\n  1  ..." becomes EXIT STATUS; any other footer NOTES.
std::string footer_section(const CLI::App& command) {
    const std::string footer = command.get_footer();
    if (footer.empty()) return "";
    std::istringstream lines(footer);
    std::string line;
    std::getline(lines, line);
    const bool exit_status = line == "Exit status:";
    std::string out = exit_status ? ".SH EXIT STATUS\n" : ".SH NOTES\n.nf\n" + roff_escape(line) + "\n";
    while (std::getline(lines, line)) {
        const auto start = line.find_first_not_of(' ');
        if (start == std::string::npos) continue;
        if (!exit_status) {
            out += roff_escape(line) + "\n";
            continue;
        }
        const auto gap = line.find(' ', start);
        const auto text = line.find_first_not_of(' ', gap);
        out += ".TP\n.B " + roff_escape(line.substr(start, gap - start)) + "\n" + roff_escape(line.substr(std::min(text, line.size()))) + "\n";
    }
    return exit_status ? out : out + ".fi\n";
}

std::string examples_section(const std::vector<std::string>& examples) {
    if (examples.empty()) return "";
    std::string out = ".SH EXAMPLES\n";
    for (const auto& example : examples) out += ".PP\n.nf\n.RS 4\n" + roff_escape(example) + "\n.RE\n.fi\n";
    return out;
}

std::string see_also(const CLI::App& root, const std::string& self) {
    std::vector<std::string> pages;
    if (self != "loopwire") pages.push_back(bold("loopwire") + "(1)");
    if (self == "loopwire" || self == "loopwire-gateway") pages.push_back(bold(config_page_name) + "(5)");
    for (const CLI::App* command : root.get_subcommands([](const CLI::App* sub) { return !sub->get_group().empty(); })) {
        const std::string page = "loopwire-" + command->get_name();
        if (page != self) pages.push_back(bold(page) + "(1)");
    }
    return ".SH SEE ALSO\n" + fmt::format("{}", fmt::join(pages, ",\n")) + "\n";
}

std::string header(const std::string& page, std::string_view summary, std::string_view version, char section = '1') {
    // Not hyphenated, not justified: option names and URLs stay whole and evenly spaced.
    return fmt::format(".TH {} {} \"\" \"loopwire {}\" \"loopwire manual\"\n.nh\n.ad l\n.SH NAME\n{} \\- {}\n", roff_escape(upper(page)),
                       section, roff_escape(version), roff_escape(page), roff_escape(summary));
}

// One key of the configuration: "name = type", its meaning, the values it takes and its default.
std::string config_key_entry(const gateway::ConfigKey& key) {
    std::string out = ".TP\n" + bold(key.key) + " = " + italic(key.type) + "\n" + sentence(key.meaning) + "\n";
    if (!key.bounds.empty()) out += ".br\nValues: " + roff_escape(key.bounds) + ".\n";
    out += ".br\n" + (key.required() ? std::string("Required.") : "Default: " + roff_escape(key.default_value) + ".") + "\n";
    return out;
}

// A verbatim block: an empty line is a zero-width character, which roff keeps as an empty line
// without a warning.
std::string verbatim(std::string_view text) {
    std::string out = ".nf\n.RS 4\n";
    std::size_t start = 0;
    while (start < text.size()) {
        auto end = text.find('\n', start);
        if (end == std::string_view::npos) end = text.size();
        const auto line = text.substr(start, end - start);
        out += line.empty() ? std::string("\\&") : roff_escape(line);
        out += "\n";
        start = end + 1;
    }
    return out + ".RE\n.fi\n";
}

// loopwire-gateway.toml(5), from the configuration's schema (gateway/config_schema.hpp): every
// table and key the gateway takes, and the complete example `--print-config` prints.
std::string config_file_page(std::string_view version) {
    std::string out = header(std::string(config_page_name), "the configuration file of loopwire gateway", version, '5');
    out += ".SH SYNOPSIS\n.B loopwire gateway \\-\\-config\n" + italic("FILE.toml") +
           "\n.br\n.B loopwire gateway \\-\\-print\\-config\n";
    out += ".SH DESCRIPTION\n" +
           sentence("A TOML file naming the lines the gateway owns, the devices on each and the fronts it serves. Every "
                    "error names the file, the line and the key, and says what is expected; `loopwire gateway --config "
                    "FILE --check` checks a file and prints the plan, and SIGHUP makes a running gateway read it again") +
           "\n.PP\n" +
           sentence("Durations are written with a unit: \"500ms\", \"1s\", \"5m\", \"1h\"; periods also in days, \"90d\". "
                    "Relative file names are taken from the configuration file's folder, and every file named must be a "
                    "regular file. An unknown key is an error, so a typo never leaves a setting at its default") +
           "\n";
    out += ".SH TABLES\n";
    for (const gateway::ConfigTable& table : gateway::config_tables()) {
        out += ".SS " + roff_escape(table.header) + "\n" + sentence(table.meaning) + "\n";
        for (const gateway::ConfigKey& key : gateway::config_keys()) {
            if (key.table == table.name) out += config_key_entry(key);
        }
    }
    out += ".SH EXAMPLE\nWhat " + bold("loopwire gateway --print-config") + " prints:\n" +
           verbatim(gateway::commented_example_config());
    return out + ".SH SEE ALSO\n" + bold("loopwire-gateway") + "(1),\n" + bold("loopwire") + "(1)\n";
}

std::string command_page(const CLI::App& root, const CLI::App& command, std::string_view version, const Examples& examples) {
    const std::string page = "loopwire-" + command.get_name();
    std::string out = header(page, command.get_description(), version);
    out += synopsis("loopwire " + command.get_name(), command, &root);
    out += ".SH DESCRIPTION\n" + sentence(command.get_description()) + "\n";
    out += options_section(command, &root);
    out += footer_section(command);
    if (const auto found = examples.find(command.get_name()); found != examples.end()) out += examples_section(found->second);
    return out + see_also(root, page);
}

std::string main_page(const CLI::App& root, std::string_view version, const Examples& examples) {
    std::string summary = root.get_description();
    if (summary.rfind("loopwire: ", 0) == 0) summary.erase(0, 10);
    std::string out = header("loopwire", summary, version);
    out += ".SH SYNOPSIS\n.B loopwire\n" + italic("COMMAND") + " [" + italic("OPTIONS") + "]\n.br\n.B loopwire \\-\\-version\n";
    out += ".SH DESCRIPTION\n" + sentence(root.get_description()) + "\nEach command has its own page, " + bold("loopwire-COMMAND") + "(1).\n";
    out += ".SH COMMANDS\n";
    for (const CLI::App* command : root.get_subcommands([](const CLI::App* sub) { return !sub->get_group().empty(); })) {
        out += ".TP\n" + bold("loopwire " + command->get_name()) + "\n" + sentence(command->get_description()) + "\n";
    }
    out += options_section(root, nullptr);
    out += footer_section(root);
    std::vector<std::string> all;
    for (const auto& [command, lines] : examples) all.insert(all.end(), lines.begin(), lines.end());
    out += examples_section(all);
    return out + see_also(root, "loopwire");
}

// The README's `sh` blocks, continuation lines joined, by command; a block showing synopses
// (options in [brackets]) is left out.
Examples readme_examples(std::string_view readme) {
    Examples examples;
    std::istringstream lines{std::string(readme)};
    std::string line;
    std::vector<std::string> block;
    bool in_block = false;
    while (std::getline(lines, line)) {
        if (line.rfind("```", 0) == 0) {
            if (in_block && std::none_of(block.begin(), block.end(), [](const std::string& l) { return l.find("[--") != std::string::npos; })) {
                for (const auto& command_line : block) {
                    if (command_line.rfind("loopwire ", 0) != 0) continue;
                    const auto start = command_line.find_first_not_of(' ', 9);
                    const auto end = command_line.find(' ', start);
                    examples[command_line.substr(start, end - start)].push_back(command_line);
                }
            }
            in_block = !in_block && line.rfind("```sh", 0) == 0;
            block.clear();
        } else if (in_block) {
            if (!block.empty() && !block.back().empty() && block.back().back() == '\\') {
                block.back().pop_back();
                block.back() += line.substr(std::min(line.find_first_not_of(' '), line.size()));
            } else {
                block.push_back(line);
            }
        }
    }
    return examples;
}

}  // namespace

std::string roff_escape(std::string_view text) {
    std::string out;
    for (std::size_t i = 0; i < text.size();) {
        const char32_t code = next_code_point(text, i);
        if (code == U'\\') out += "\\e";
        else if (code == U'-') out += "\\-";
        else if (code == U'\n') out += "\n";
        else if (code >= 0x80) out += fmt::format("\\[u{:04X}]", static_cast<std::uint32_t>(code));
        else out += static_cast<char>(code);
        if (code == U'\n' && i < text.size() && (text[i] == '.' || text[i] == '\'')) out += "\\&";
    }
    if (!out.empty() && (out.front() == '.' || out.front() == '\'')) out.insert(0, "\\&");
    return out;
}

std::vector<ManPage> man_pages(const CLI::App& root, std::string_view version, std::string_view readme) {
    const Examples examples = readme_examples(readme);
    std::vector<ManPage> pages{{"loopwire.1", main_page(root, version, examples)}};
    for (const CLI::App* command : root.get_subcommands([](const CLI::App* sub) { return !sub->get_group().empty(); })) {
        pages.push_back({"loopwire-" + command->get_name() + ".1", command_page(root, *command, version, examples)});
    }
    pages.push_back({std::string(config_page_name) + ".5", config_file_page(version)});
    return pages;
}

}  // namespace loopwire::app
