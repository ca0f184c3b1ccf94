#include "app/completion.hpp"

#include <algorithm>
#include <cctype>
#include <string_view>

#include "profile/profile.hpp"

namespace loopwire::app {
namespace {

// What the words before the one being completed say: the command, its positionals so far, the
// --profile files and --device values given, and the option still waiting for its value.
struct LineState {
    const CLI::App* command = nullptr;
    std::vector<std::string> positionals;
    std::vector<std::string> profile_files;
    std::vector<std::string> devices;  // DEVICE@UNIT
    const CLI::Option* awaiting = nullptr;
};

std::string lower(std::string_view text) {
    std::string out(text);
    std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return out;
}

bool starts_with(std::string_view text, std::string_view prefix) { return text.substr(0, prefix.size()) == prefix; }

bool takes_value(const CLI::Option& option) { return option.get_items_expected_max() > 0; }  // flags expect 0

// `name` (--long or -s) among the options of `command` and of the commands it falls through to
// (--profile and --help follow every subcommand's name).
const CLI::Option* find_option(const CLI::App* command, const std::string& name) {
    for (const CLI::App* at = command; at != nullptr; at = at->get_fallthrough() ? at->get_parent() : nullptr) {
        for (const CLI::Option* option : at->get_options()) {
            if (!option->get_positional() && option->check_name(name)) return option;
        }
    }
    return nullptr;
}

std::vector<const CLI::App*> visible_subcommands(const CLI::App& command) {
    return command.get_subcommands([](const CLI::App* sub) { return !sub->get_group().empty(); });
}

const CLI::App* find_subcommand(const CLI::App& command, const std::string& name) {
    auto found = command.get_subcommands([&](const CLI::App* sub) { return sub->check_name(name); });
    return found.empty() ? nullptr : found.front();
}

void remember_value(LineState& state, const CLI::Option& option, const std::string& value) {
    if (option.check_lname("profile")) state.profile_files.push_back(value);
    if (option.check_lname("device")) state.devices.push_back(value);
}

// Reads an option word at `typed[i]`; returns the index of the last word it consumed.
std::size_t read_option(LineState& state, const std::vector<std::string>& typed, std::size_t i) {
    const std::string& word = typed[i];
    const auto equals = word.find('=');
    const CLI::Option* option = find_option(state.command, word.substr(0, equals));
    if (option == nullptr || !takes_value(*option)) return i;
    if (equals != std::string::npos) {
        remember_value(state, *option, word.substr(equals + 1));
        return i;
    }
    if (i + 2 == typed.size()) {  // its value is the word being completed
        state.awaiting = option;
        return i + 1;
    }
    remember_value(state, *option, typed[i + 1]);
    return i + 1;
}

LineState read_line(const CLI::App& root, const std::vector<std::string>& typed) {
    LineState state;
    state.command = &root;
    bool options_ended = false;
    for (std::size_t i = 0; i + 1 < typed.size(); ++i) {
        const std::string& word = typed[i];
        if (!options_ended && word == "--") {
            options_ended = true;
        } else if (!options_ended && word.size() > 1 && word[0] == '-') {
            i = read_option(state, typed, i);
            if (state.awaiting != nullptr) break;
        } else if (state.command == &root && find_subcommand(root, word) != nullptr) {
            state.command = find_subcommand(root, word);
        } else {
            state.positionals.push_back(word);
        }
    }
    return state;
}

std::vector<std::string> option_names(const CLI::App* command) {
    std::vector<std::string> names;
    for (const CLI::App* at = command; at != nullptr; at = at->get_fallthrough() ? at->get_parent() : nullptr) {
        for (const CLI::Option* option : at->get_options()) {
            if (option->get_group().empty()) continue;  // hidden
            for (const auto& name : option->get_lnames()) names.push_back("--" + name);
            for (const auto& name : option->get_snames()) names.push_back("-" + name);
        }
    }
    return names;
}

// The choices of a CLI::IsMember check, which CLI11 writes into the type name: "TEXT:{a,b,c}".
std::vector<std::string> member_choices(const CLI::Option& option) {
    const std::string type = option.get_type_name();
    const auto open = type.find('{');
    const auto close = type.find('}', open);
    if (open == std::string::npos || close == std::string::npos) return {};
    std::vector<std::string> choices;
    std::string_view list(type.data() + open + 1, close - open - 1);
    while (!list.empty()) {
        const auto comma = std::min(list.find(','), list.size());
        choices.emplace_back(list.substr(0, comma));
        list.remove_prefix(std::min(comma + 1, list.size()));
    }
    return choices;
}

// The tables a raw TABLE ADDRESS argument takes, as its help lists them: "TABLE ADDRESS ...:
// holding|input|coils|discrete, ...".
std::vector<std::string> table_choices(const CLI::Option& positional) {
    const std::string& help = positional.get_description();
    const auto form = help.find("TABLE ADDRESS");
    const auto colon = help.find(": ", form);
    if (form == std::string::npos || colon == std::string::npos) return {};
    const auto end = help.find_first_of(", ", colon + 2);
    std::string_view list(help.data() + colon + 2, (end == std::string::npos ? help.size() : end) - colon - 2);
    std::vector<std::string> tables;
    while (!list.empty()) {
        const auto bar = std::min(list.find('|'), list.size());
        tables.emplace_back(list.substr(0, bar));
        list.remove_prefix(std::min(bar + 1, list.size()));
    }
    return tables;
}

// Options whose value names a file: their type name or help says FILE or PATH (--profile
// FILE.json, --output FILE, --pty PATH, ...).
bool wants_path(const CLI::Option& option) {
    const std::string text = option.get_type_name() + " " + option.get_description();
    return text.find("FILE") != std::string::npos || text.find("PATH") != std::string::npos;
}

std::string device_id(const std::string& device_at_unit) { return device_at_unit.substr(0, device_at_unit.find('@')); }

struct Candidates {
    const std::vector<std::string>& profile_files;
    const ProfileLoader& load;

    std::vector<std::string> device_ids(std::string_view suffix) const {
        std::vector<std::string> ids;
        auto registry = load(profile_files);
        if (!registry) return ids;
        for (const auto& id : registry->ids()) ids.push_back(id + std::string(suffix));
        return ids;
    }

    // Names, mnemonics (in the case typed: they match in any) and groups of each device;
    // `assignment`: writable ones only, as NAME= for write's NAME=VALUE.
    std::vector<std::string> parameters(const std::vector<std::string>& devices, bool assignment, bool upper_case) const {
        std::vector<std::string> names;
        auto registry = load(profile_files);
        if (!registry) return names;
        if (!assignment) names.emplace_back("all");
        for (const auto& device : devices) {
            auto profile = registry->find(device_id(device));
            if (!profile) continue;
            for (const auto& parameter : (*profile)->parameters) {
                if (parameter.hidden || (assignment ? !parameter.writable : !parameter.readable)) continue;
                const std::string suffix = assignment ? "=" : "";
                names.push_back(parameter.name + suffix);
                if (!parameter.mnemonic.empty()) names.push_back((upper_case ? parameter.mnemonic : lower(parameter.mnemonic)) + suffix);
                if (!assignment && !parameter.group.empty()) names.push_back(parameter.group);
            }
        }
        return names;
    }

    std::vector<std::string> groups(const std::string& device) const {
        std::vector<std::string> names;
        auto registry = load(profile_files);
        if (!registry) return names;
        auto profile = registry->find(device_id(device));
        if (!profile) return names;
        for (const auto& parameter : (*profile)->parameters) {
            if (!parameter.group.empty()) names.push_back(parameter.group);
        }
        return names;
    }
};

bool has_upper(std::string_view text) {
    return std::any_of(text.begin(), text.end(), [](unsigned char c) { return std::isupper(c) != 0; });
}

Completion complete_value(const CLI::Option& option, const LineState& state, const Candidates& candidates) {
    if (option.check_lname("device")) return {false, candidates.device_ids("@")};
    if (option.check_lname("group")) {  // describe DEVICE --group G
        const auto& devices = state.devices.empty() ? state.positionals : state.devices;
        return {false, devices.empty() ? std::vector<std::string>{} : candidates.groups(devices.front())};
    }
    if (wants_path(option)) return {true, {}};
    return {false, member_choices(option)};
}

// The positional option the next positional word of `command` goes to.
const CLI::Option* positional_at(const CLI::App& command, std::size_t index) {
    for (const CLI::Option* option : command.get_options([](const CLI::Option* o) { return o->get_positional(); })) {
        const auto most = static_cast<std::size_t>(std::max(option->get_items_expected_max(), 0));
        if (index < most) return option;
        index -= most;
    }
    return nullptr;
}

Completion command_names(const CLI::App& root) {
    Completion out;
    for (const CLI::App* sub : visible_subcommands(root)) out.words.push_back(sub->get_name());
    return out;
}

Completion complete_positional(const CLI::App& root, const LineState& state, const std::string& current, const Candidates& candidates) {
    if (state.command == &root) return command_names(root);
    const CLI::Option* positional = positional_at(*state.command, state.positionals.size());
    if (positional == nullptr) return {};
    if (positional->check_name("command")) return command_names(root);  // a command about commands
    if (positional->check_name("device")) return {false, candidates.device_ids("")};
    if (positional->check_name("file")) return {true, {}};
    if (state.devices.empty()) return {false, state.positionals.empty() ? table_choices(*positional) : std::vector<std::string>{}};
    const bool assignment = positional->get_description().find("NAME=VALUE") != std::string::npos;
    return {false, candidates.parameters(state.devices, assignment, has_upper(current))};
}

bool matches(const std::string& candidate, const std::string& current) {
    return starts_with(candidate, current) || starts_with(lower(candidate), lower(current));
}

}  // namespace

Completion complete_command_line(const CLI::App& root, const std::vector<std::string>& words, const ProfileLoader& load_profiles) {
    std::vector<std::string> typed = words;
    if (typed.empty()) typed.emplace_back();
    const std::string current = typed.back();
    const LineState state = read_line(root, typed);
    const Candidates candidates{state.profile_files, load_profiles};
    Completion out;
    if (state.awaiting != nullptr) {
        out = complete_value(*state.awaiting, state, candidates);
    } else if (!current.empty() && current[0] == '-') {
        out.words = option_names(state.command);
    } else {
        out = complete_positional(root, state, current, candidates);
    }
    std::erase_if(out.words, [&](const std::string& word) { return !matches(word, current) || word.find(' ') != std::string::npos; });
    std::sort(out.words.begin(), out.words.end());
    out.words.erase(std::unique(out.words.begin(), out.words.end()), out.words.end());
    return out;
}

}  // namespace loopwire::app
