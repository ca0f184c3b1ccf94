#include "profile/profile_checks.hpp"

#include <algorithm>
#include <charconv>
#include <map>
#include <optional>
#include <set>
#include <string>

#include <fmt/format.h>

#include "codec/table.hpp"
#include "profile/value_text.hpp"

namespace loopwire::device {
namespace {

using Json = nlohmann::json;

std::string parameter_pointer(std::size_t index, const std::string& rest = {}) {
    return fmt::format("/parameters/{}{}", index, rest);
}

// Keys the schema restricts to decimal digits, which may still overflow; nullopt then.
std::optional<long long> integer_key(const std::string& key) {
    long long value = 0;
    const auto [end, error] = std::from_chars(key.data(), key.data() + key.size(), value);
    if (error != std::errc() || end != key.data() + key.size()) return std::nullopt;
    return value;
}

bool has_note(const Json& parameter) {
    return parameter.contains("note") && !parameter.at("note").get<std::string>().empty();
}

// "all" names every readable parameter on the command line (`loopwire read ... all`): a parameter,
// mnemonic or group called so would be read instead of them.
void check_reserved_words(const Json& parameters, std::vector<DocumentProblem>& problems) {
    for (std::size_t i = 0; i < parameters.size(); ++i) {
        for (const char* key : {"name", "mnemonic", "group"}) {
            const auto found = parameters[i].find(key);
            if (found == parameters[i].end() || !found->is_string()) continue;
            if (!equal_ignoring_case(found->get<std::string>(), "all")) continue;
            problems.push_back({parameter_pointer(i, std::string("/") + key),
                                fmt::format("\"{}\" is reserved: `loopwire read ... all` reads every readable parameter; "
                                            "call it otherwise", found->get<std::string>())});
        }
    }
}

void check_unique_names(const Json& parameters, std::vector<DocumentProblem>& problems) {
    check_reserved_words(parameters, problems);
    std::map<std::string, std::size_t> first_index;
    for (std::size_t i = 0; i < parameters.size(); ++i) {
        const auto name = parameters[i].at("name").get<std::string>();
        const auto [it, inserted] = first_index.emplace(name, i);
        if (!inserted) {
            problems.push_back({parameter_pointer(i, "/name"),
                                fmt::format("duplicate name \"{}\" (also {})", name, parameter_pointer(it->second))});
        }
    }
}

void check_unique_addresses(const Json& parameters, std::vector<DocumentProblem>& problems) {
    std::map<std::pair<std::string, int>, std::size_t> first_index;
    for (std::size_t i = 0; i < parameters.size(); ++i) {
        const Json& parameter = parameters[i];
        const auto key = std::make_pair(parameter.at("table").get<std::string>(), parameter.at("address").get<int>());
        const auto [it, inserted] = first_index.emplace(key, i);
        if (inserted) continue;
        const Json& other = parameters[it->second];
        if (has_note(parameter) && has_note(other)) continue;  // a glitch explained on both entries
        problems.push_back({parameter_pointer(i, "/address"),
                            fmt::format("{} {} is also the address of {} ({}); two entries may share an address "
                                        "only if both carry a \"note\" explaining the manual glitch",
                                        key.first, key.second, parameter_pointer(it->second),
                                        other.at("name").get<std::string>())});
    }
}

class ReferenceCheck {
public:
    ReferenceCheck(const Json& document, std::vector<DocumentProblem>& problems) : problems_(problems) {
        for (const Json& parameter : document.at("parameters")) names_.insert(parameter.at("name").get<std::string>());
    }

    // `pointer` locates the referring string itself; `self` is the referring parameter, if any.
    void check(const Json& name, const std::string& pointer, const std::string& self = {}) {
        const auto text = name.get<std::string>();
        if (!names_.contains(text)) {
            problems_.push_back({pointer, fmt::format("no parameter named \"{}\"", text)});
        } else if (text == self) {
            problems_.push_back({pointer, fmt::format("\"{}\" refers to itself", text)});
        }
    }

private:
    std::set<std::string> names_;
    std::vector<DocumentProblem>& problems_;
};

void check_parameter_references(const Json& parameters, ReferenceCheck& references) {
    for (std::size_t i = 0; i < parameters.size(); ++i) {
        const Json& parameter = parameters[i];
        const auto self = parameter.at("name").get<std::string>();
        if (const auto decimals = parameter.find("decimals"); decimals != parameter.end() && decimals->is_object()) {
            references.check(decimals->at("parameter"), parameter_pointer(i, "/decimals/parameter"), self);
        }
        const Json unit_from = parameter.value("unit_from", Json::array());
        for (std::size_t k = 0; k < unit_from.size(); ++k) {
            references.check(unit_from[k].at("parameter"), parameter_pointer(i, fmt::format("/unit_from/{}/parameter", k)), self);
        }
        const auto range = parameter.find("range");
        if (range == parameter.end()) continue;
        for (const char* bound : {"min", "max"}) {
            if (const auto value = range->find(bound); value != range->end() && value->is_object()) {
                references.check(value->at("parameter"), parameter_pointer(i, fmt::format("/range/{}/parameter", bound)),
                                 self);
            }
        }
    }
}

// What a command line can carry as one name: no spaces, no '=' (NAME=VALUE), no ':' (DEVICE:NAME).
bool alias_word(const std::string& alias) {
    const auto word_character = [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
    };
    return !alias.empty() && alias.front() != '-' && std::all_of(alias.begin(), alias.end(), word_character);
}

void check_top_level_references(const Json& document, ReferenceCheck& references,
                                 std::vector<DocumentProblem>& problems) {
    // A device described by its points alone has nothing it can be recognised by.
    const Json identification = document.value("identification", Json::object({{"match", Json::array()}}));
    const Json& match = identification.at("match");
    for (std::size_t k = 0; k < match.size(); ++k) {
        const std::string pointer = fmt::format("/identification/match/{}", k);
        references.check(match[k].at("parameter"), pointer + "/parameter");
        if (!match[k].contains("equals")) problems.push_back({pointer, "an identification match needs \"equals\""});
    }
    if (const auto report = identification.find("report"); report != identification.end()) {
        for (std::size_t k = 0; k < report->size(); ++k) {
            references.check((*report)[k], fmt::format("/identification/report/{}", k));
        }
    }
    if (const auto requirements = document.find("mode_requirements"); requirements != document.end()) {
        for (const auto& [mode, checks] : requirements->items()) {
            for (std::size_t k = 0; k < checks.size(); ++k) {
                const std::string pointer = fmt::format("/mode_requirements/{}/{}", mode, k);
                references.check(checks[k].at("parameter"), pointer + "/parameter");
                if (!checks[k].contains("equals")) problems.push_back({pointer, "a mode requirement needs \"equals\""});
            }
        }
    }
    const Json aliases = document.value("aliases", Json::object());  // held: items() refers to it
    for (const auto& [alias, name] : aliases.items()) {
        references.check(name, "/aliases/" + alias);
        if (!alias_word(alias)) {
            problems.push_back({"/aliases/" + alias, "an alias is one word as people type it: letters, digits, '.', '_' or '-'"});
        }
    }
    const Json& addressing = document.at("addressing");
    if (const auto alternatives = addressing.find("alternatives"); alternatives != addressing.end()) {
        for (std::size_t k = 0; k < alternatives->size(); ++k) {
            const std::string pointer = fmt::format("/addressing/alternatives/{}/selected_by", k);
            const Json& selector = (*alternatives)[k].at("selected_by");
            references.check(selector.at("parameter"), pointer + "/parameter");
            if (!selector.contains("equals")) problems.push_back({pointer, "a numbering selector needs \"equals\""});
        }
    }
}

void check_write_modes(const Json& document, std::vector<DocumentProblem>& problems) {
    const Json modes = document.value("modes", Json::object());
    const Json& parameters = document.at("parameters");
    for (std::size_t i = 0; i < parameters.size(); ++i) {
        const Json write_modes = parameters[i].value("write_modes", Json::array());
        for (std::size_t k = 0; k < write_modes.size(); ++k) {
            const auto mode = write_modes[k].get<std::string>();
            if (!modes.contains(mode)) {
                problems.push_back({parameter_pointer(i, fmt::format("/write_modes/{}", k)),
                                    fmt::format("no mode named \"{}\" in /modes", mode)});
            }
        }
    }
    const Json requirements = document.value("mode_requirements", Json::object());
    for (const auto& [mode, checks] : requirements.items()) {
        if (!modes.contains(mode)) problems.push_back({"/mode_requirements/" + mode, fmt::format("no mode named \"{}\" in /modes", mode)});
    }
}

void check_parameter_values(const Json& parameters, std::vector<DocumentProblem>& problems) {
    for (std::size_t i = 0; i < parameters.size(); ++i) {
        const Json& parameter = parameters[i];
        const auto table = parameter.at("table").get<std::string>();
        const auto named = codec::table_named(table);
        const bool bit_table = named && codec::is_bit_table(*named);
        if (bit_table != (parameter.at("type") == "bool")) {
            problems.push_back({parameter_pointer(i, "/type"),
                                bit_table ? fmt::format("entries of table {} must be bool", table)
                                          : fmt::format("bool entries belong in coils or discrete, not {}", table)});
        }
        for (const auto& [key, label] : object_member(parameter, "enum").items()) {
            const auto raw = integer_key(key);
            if (!raw || *raw < -32768 || *raw > 65535) {
                problems.push_back({parameter_pointer(i, "/enum/" + key), "raw value must be within -32768..65535"});
            }
        }
        const Json range = parameter.value("range", Json::object());
        if (range.contains("min") && range.contains("max") && range.at("min").is_number() &&
            range.at("max").is_number() && range.at("min").get<double>() > range.at("max").get<double>()) {
            problems.push_back({parameter_pointer(i, "/range"),
                                fmt::format("min {} is above max {}", range.at("min").dump(), range.at("max").dump())});
        }
    }
}

// Values carry their units: a number (int16/uint16) says its unit, where its unit comes from,
// or why it has none; the three are exclusive. Enums, bit fields and bools are not quantities.
void check_units(const Json& parameters, std::vector<DocumentProblem>& problems) {
    for (std::size_t i = 0; i < parameters.size(); ++i) {
        const Json& parameter = parameters[i];
        const bool number = parameter.at("type") == "int16" || parameter.at("type") == "uint16";
        const bool fixed = !parameter.value("unit", std::string()).empty();
        const bool follows = parameter.contains("unit_from");
        const bool unitless = parameter.contains("unitless");
        const int given = int{fixed} + int{follows} + int{unitless};
        if (number && given == 0) {
            problems.push_back({parameter_pointer(i), "a number needs \"unit\", \"unit_from\" (the unit follows another "
                                                      "word) or \"unitless\" (count, code, ratio, raw)"});
        } else if (given > 1) {
            problems.push_back({parameter_pointer(i), "give only one of \"unit\", \"unit_from\" and \"unitless\""});
        } else if (!number && (follows || unitless)) {
            problems.push_back({parameter_pointer(i), "\"unit_from\" and \"unitless\" are for numbers (int16, uint16)"});
        }
        const Json unit_from = parameter.value("unit_from", Json::array());
        for (std::size_t k = 0; k < unit_from.size(); ++k) {
            for (const auto& [key, unit] : object_member(unit_from[k], "units").items()) {
                const auto raw = integer_key(key);
                if (!raw || *raw < -32768 || *raw > 65535) {
                    problems.push_back({parameter_pointer(i, fmt::format("/unit_from/{}/units/{}", k, key)),
                                        "raw value must be within -32768..65535"});
                }
            }
        }
    }
}

// unit_ids: whole addresses a serial line can carry, 1..255 (0 is broadcast).
void check_unit_ids(const Json& document, std::vector<DocumentProblem>& problems) {
    const auto units = document.find("unit_ids");
    if (units == document.end()) return;
    const Json& first = units->at("min");
    const Json& last = units->at("max");
    const bool whole = first.is_number_integer() && last.is_number_integer();
    if (!whole || first.get<long long>() < 1 || last.get<long long>() > 255 || first.get<long long>() > last.get<long long>()) {
        problems.push_back({"/unit_ids", "need whole numbers 1 <= min <= max <= 255 (0 is broadcast)"});
    }
}

void check_codes_and_mirrors(const Json& document, std::vector<DocumentProblem>& problems) {
    for (const auto& [code, meaning] : object_member(document, "exceptions").items()) {
        const auto value = integer_key(code);
        if (!value || *value < 1 || *value > 255) problems.push_back({"/exceptions/" + code, "exception codes are 1..255"});
    }
    const Json mirrors = document.at("addressing").value("mirrors", Json::array());
    for (std::size_t k = 0; k < mirrors.size(); ++k) {
        const auto first = mirrors[k].at("first").get<long long>();
        const auto last = mirrors[k].at("last").get<long long>();
        const auto offset = mirrors[k].at("offset").get<long long>();
        if (first > last || first < 0 || last > 65535 || first + offset < 0 || last + offset > 65535) {
            problems.push_back({fmt::format("/addressing/mirrors/{}", k),
                                "need 0 <= first <= last <= 65535 with first..last + offset within 0..65535"});
        }
    }
}

}  // namespace

std::vector<DocumentProblem> semantic_problems(const Json& document) {
    std::vector<DocumentProblem> problems;
    const Json& parameters = document.at("parameters");
    check_unique_names(parameters, problems);
    check_unique_addresses(parameters, problems);
    ReferenceCheck references(document, problems);
    check_parameter_references(parameters, references);
    check_top_level_references(document, references, problems);
    check_write_modes(document, problems);
    check_parameter_values(parameters, problems);
    check_units(parameters, problems);
    check_unit_ids(document, problems);
    check_codes_and_mirrors(document, problems);
    return problems;
}

}  // namespace loopwire::device
