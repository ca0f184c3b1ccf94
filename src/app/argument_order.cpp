#include "app/argument_order.hpp"

#include <algorithm>
#include <cstddef>
#include <optional>

namespace loopwire::app {
namespace {

bool is_option(const std::string& argument) { return argument.size() > 1 && argument[0] == '-' && argument != "--"; }

// "--timeout=2s" -> "--timeout"; "-v" stays.
std::string option_name(const std::string& argument) {
    const auto equals = argument.find('=');
    return argument.rfind("--", 0) == 0 && equals != std::string::npos ? argument.substr(0, equals) : argument;
}

// How many words the option at `arguments[at]` spans (itself and its value), as `owner` defines
// it; nothing when `owner` does not know it.
std::optional<std::size_t> option_span(const CLI::App& owner, const std::vector<std::string>& arguments, std::size_t at) {
    const std::string name = option_name(arguments[at]);
    const CLI::Option* option = owner.get_option_no_throw(name);
    if (option == nullptr) return std::nullopt;
    const bool inline_value = name.size() != arguments[at].size();
    if (option->get_expected_max() == 0 || inline_value) return 1;  // a flag expects no value
    return at + 1 < arguments.size() ? 2 : 1;
}

const CLI::App* subcommand_named(const CLI::App& app, const std::string& name) {
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
        if (sub->check_name(name)) return sub;
    }
    return nullptr;
}

}  // namespace

std::vector<std::string> options_after_command(const CLI::App& app, const std::vector<std::string>& arguments) {
    // Find the subcommand: the first word that is neither an option nor the value of one.
    std::size_t at = 0;
    const CLI::App* command = nullptr;
    std::vector<std::size_t> moved;  // indices of the words to move after the command's name
    while (at < arguments.size()) {
        const std::string& argument = arguments[at];
        if (!is_option(argument)) {
            command = subcommand_named(app, argument);
            break;
        }
        if (const auto own = option_span(app, arguments, at)) {  // the program's own: stays
            at += *own;
            continue;
        }
        // Not the program's: whose it is is known only once the command is; assume a flag unless
        // some subcommand gives it a value.
        std::size_t span = 1;
        for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
            if (const auto their = option_span(*sub, arguments, at)) span = std::max(span, *their);
        }
        for (std::size_t i = 0; i < span; ++i) moved.push_back(at + i);
        at += span;
    }
    if (command == nullptr || moved.empty()) return arguments;
    for (std::size_t index : moved) {  // only options this command knows are moved
        if (is_option(arguments[index]) && !command->get_option_no_throw(option_name(arguments[index]))) return arguments;
    }
    std::vector<std::string> reordered;
    for (std::size_t i = 0; i < at; ++i) {
        if (std::find(moved.begin(), moved.end(), i) == moved.end()) reordered.push_back(arguments[i]);
    }
    reordered.push_back(arguments[at]);
    for (std::size_t index : moved) reordered.push_back(arguments[index]);
    reordered.insert(reordered.end(), arguments.begin() + static_cast<std::ptrdiff_t>(at) + 1, arguments.end());
    return reordered;
}

}  // namespace loopwire::app
