// resolve_parameters (request_planner.hpp): what a user names on the command line to profile
// entries. Beyond what request_planner.hpp says: aliases, mnemonics and groups also match with
// the manuals' non-ASCII letters typed in ASCII (AC20 "m.OLL" for "ñ.OLL": folded_name), and a
// miss offers up to three nearest names (name_matching.hpp).
#include <algorithm>

#include <cctype>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "profile/name_matching.hpp"
#include "profile/request_planner.hpp"
#include "profile/value_text.hpp"

namespace loopwire::device {
namespace {

using Found = std::vector<const Parameter*>;

Found by_name(const Profile& profile, const std::string& name) {
    if (const Parameter* exact = profile.find(name)) return {exact};
    for (const Parameter& parameter : profile.parameters) {
        if (equal_ignoring_case(parameter.name, name)) return {&parameter};
    }
    return {};
}

Found by_alias(const Profile& profile, const std::string& text) {
    for (const auto& [alias, name] : profile.aliases) {
        if (same_name(text, alias)) return {profile.find(name)};  // the checks made sure it exists
    }
    return {};
}

Found matching(const Profile& profile, const std::string& text, const std::string Parameter::*field,
               bool readable_only) {
    Found found;
    for (const Parameter& parameter : profile.parameters) {
        if (readable_only && !parameter.readable) continue;
        const std::string& value = parameter.*field;
        if (!value.empty() && same_name(text, value)) found.push_back(&parameter);
    }
    return found;
}

// "all" is what a full read means: every readable entry except those the profile marks hidden
// (service words the manual hides from users; name them or their group to read them).
Found every_readable(const Profile& profile) {
    Found found;
    for (const Parameter& parameter : profile.parameters) {
        if (parameter.readable && !parameter.hidden) found.push_back(&parameter);
    }
    return found;
}

Error ambiguous(const std::string& text, const Found& candidates) {
    std::string listed;
    for (const Parameter* parameter : candidates) {
        listed += fmt::format("{}{} ({}, {} {})", listed.empty() ? "" : ", ", parameter->name, parameter->mnemonic,
                              table_name(parameter->table), parameter->address);
    }
    return make_error(ErrorKind::usage,
                      fmt::format("mnemonic \"{}\" is ambiguous: {}; use the name instead", text, listed));
}

// "no parameter "sett_point" on tc10; did you mean set_point (SP)?": the nearest names,
// mnemonics, aliases and groups (name_matching.hpp), or where to look them up.
Error not_found(const Profile& profile, const std::string& text) {
    const auto nearest = nearest_names(profile, text);
    if (nearest.empty()) {
        return make_error(ErrorKind::usage, fmt::format("no parameter \"{}\" on {}; `loopwire describe {}` lists its names, "
                                                        "mnemonics and groups", text, profile.id, profile.id));
    }
    std::string listed = nearest.front();
    for (std::size_t i = 1; i < nearest.size(); ++i) listed += (i + 1 == nearest.size() ? " or " : ", ") + nearest[i];
    return make_error(ErrorKind::usage, fmt::format("no parameter \"{}\" on {}; did you mean {}?", text, profile.id, listed));
}

Result<Found> resolve_one(const Profile& profile, const std::string& text) {
    const std::string group_prefix = "group:";
    if (text.size() > group_prefix.size() && equal_ignoring_case(text.substr(0, group_prefix.size()), group_prefix)) {
        const std::string group = text.substr(group_prefix.size());
        if (Found found = matching(profile, group, &Parameter::group, true); !found.empty()) return found;
        return make_error(ErrorKind::usage, fmt::format("profile {} has no group \"{}\" with readable parameters; its groups: {}",
                                                        profile.id, group, fmt::join(group_names(profile), ", ")));
    }
    if (Found found = by_name(profile, text); !found.empty()) return found;
    if (Found found = by_alias(profile, text); !found.empty()) return found;
    if (Found found = matching(profile, text, &Parameter::mnemonic, false); !found.empty()) {
        if (found.size() > 1) return ambiguous(text, found);
        return found;
    }
    if (Found found = matching(profile, text, &Parameter::group, true); !found.empty()) return found;
    if (equal_ignoring_case(text, "all")) return every_readable(profile);
    return not_found(profile, text);
}

}  // namespace

Result<std::vector<const Parameter*>> resolve_parameters(const Profile& profile, const std::vector<std::string>& names) {
    std::vector<const Parameter*> resolved;
    for (const std::string& name : names) {
        auto found = resolve_one(profile, std::string(trimmed(name)));
        if (!found) return found.error();
        for (const Parameter* parameter : *found) {
            if (std::find(resolved.begin(), resolved.end(), parameter) == resolved.end()) resolved.push_back(parameter);
        }
    }
    return resolved;
}

}  // namespace loopwire::device
