#include "profile/profile_conversion.hpp"

#include <string>

#include "profile/json_document.hpp"

namespace loopwire::device {
namespace {

using Json = nlohmann::json;

// The schema allows only the four names (profile_schema): anything else is a holding register.
Table table_from(const Json& text) { return codec::table_named(text.get<std::string>()).value_or(Table::holding_registers); }

ValueType type_from(const Json& text) {
    const auto name = text.get<std::string>();
    if (name == "int16") return ValueType::int16;
    if (name == "enum") return ValueType::enumeration;
    if (name == "bitfield") return ValueType::bitfield;
    if (name == "bool") return ValueType::boolean;
    return ValueType::uint16;
}

Bound bound_from(const Json& value) {
    if (value.is_object()) return value.at("parameter").get<std::string>();
    return value.get<double>();
}

std::vector<SpecialValue> specials_from(const Json& list) {
    std::vector<SpecialValue> specials;
    for (const Json& entry : list) {
        specials.push_back({entry.at("raw").get<std::int32_t>(), entry.at("state").get<std::string>(),
                            entry.value("meaning", std::string())});
    }
    return specials;
}

void read_range(const Json& entry, Parameter& parameter) {
    const auto range = entry.find("range");
    if (range == entry.end()) return;
    if (range->contains("min")) parameter.min = bound_from(range->at("min"));
    if (range->contains("max")) parameter.max = bound_from(range->at("max"));
    parameter.range_in_counts = range->value("counts", false);
}

void read_labels(const Json& entry, Parameter& parameter) {
    for (const auto& [key, label] : object_member(entry, "enum").items()) {
        parameter.enum_labels.emplace(std::stoi(key), label.get<std::string>());
    }
    for (const auto& [key, name] : object_member(entry, "bits").items()) {
        parameter.bit_names.emplace(static_cast<unsigned>(std::stoul(key)), name.get<std::string>());
    }
}

Parameter parameter_from(const Json& entry, const std::vector<SpecialValue>& word_specials) {
    Parameter parameter;
    parameter.name = entry.at("name").get<std::string>();
    parameter.mnemonic = entry.value("mnemonic", std::string());
    parameter.group = entry.value("group", std::string());
    parameter.description = entry.value("description", std::string());
    parameter.table = table_from(entry.at("table"));
    parameter.address = entry.at("address").get<std::uint16_t>();
    parameter.type = type_from(entry.at("type"));
    if (const auto decimals = entry.find("decimals"); decimals != entry.end()) {
        if (decimals->is_object()) parameter.decimals = decimals->at("parameter").get<std::string>();
        else parameter.decimals = decimals->get<int>();
    }
    parameter.unit = entry.value("unit", std::string());
    for (const Json& rule : entry.value("unit_from", Json::array())) {
        UnitRule unit_rule{rule.at("parameter").get<std::string>(), {}};
        for (const auto& [key, unit] : rule.at("units").items()) unit_rule.units.emplace(std::stoi(key), unit.get<std::string>());
        parameter.unit_from.push_back(std::move(unit_rule));
    }
    parameter.unitless = entry.value("unitless", std::string());
    const auto access = entry.at("access").get<std::string>();
    parameter.readable = access.find('r') != std::string::npos;
    parameter.writable = access.find('w') != std::string::npos;
    parameter.write_modes = entry.value("write_modes", std::vector<std::string>());
    read_range(entry, parameter);
    read_labels(entry, parameter);
    parameter.special = specials_from(entry.value("special", Json::array()));
    if (parameter.table == Table::holding_registers || parameter.table == Table::input_registers) {
        parameter.special.insert(parameter.special.end(), word_specials.begin(), word_specials.end());
    }
    parameter.ram_only = entry.value("storage", std::string()) == "ram";
    parameter.persistent = entry.value("storage", std::string()) == "persistent";
    parameter.hidden = entry.value("hidden", false);
    parameter.source = entry.at("source").get<std::string>();
    parameter.note = entry.value("note", std::string());
    return parameter;
}

Limits limits_from(const Json& limits) {
    Limits result;
    result.read_bits = limits.value("read_bits", result.read_bits);
    result.read_registers = limits.value("read_registers", result.read_registers);
    result.write_bits = limits.value("write_bits", result.write_bits);
    result.write_registers = limits.value("write_registers", result.write_registers);
    return result;
}

void read_line(const Json& document, Profile& profile) {
    profile.protocols = document.at("protocols").get<std::vector<std::string>>();
    const Json& serial = document.at("serial_defaults");
    profile.default_baud = serial.at("baud").get<std::uint32_t>();
    profile.default_data_bits = serial.at("data_bits").get<unsigned>();
    profile.default_parity = serial.at("parity").get<std::string>();
    profile.default_stop_bits = serial.at("stop_bits").get<unsigned>();
    profile.function_codes = document.at("function_codes").get<std::vector<std::uint8_t>>();
    profile.limits = limits_from(document.at("limits"));
    profile.parities = serial.value("parities", std::vector<std::string>{profile.default_parity});
    profile.broadcast = document.value("broadcast", false);
    if (const auto units = document.find("unit_ids"); units != document.end()) {
        profile.first_unit = units->value("min", profile.first_unit);
        profile.last_unit = units->value("max", profile.last_unit);
    }
    profile.unmapped_reads_answered = document.at("unmapped_reads") == "answered";
    profile.unmapped_value = document.value("unmapped_value", profile.unmapped_value);
    profile.silent_on_unsupported_function = document.value("silent_on_unsupported_function", false);
    profile.limit_exception = document.value("limit_exception", profile.limit_exception);
    profile.read_only_writes_ignored = document.value("read_only_writes", std::string()) == "ignored";
    profile.block_writes_in_order = document.value("block_writes", std::string()) == "in-order";
    for (const auto& [code, meaning] : object_member(document, "exceptions").items()) {
        profile.exception_names.emplace(static_cast<std::uint8_t>(std::stoi(code)), meaning.get<std::string>());
    }
}

void read_addressing(const Json& addressing, Profile& profile) {
    for (const Json& entry : addressing.value("alternatives", Json::array())) {
        const Json& selector = entry.at("selected_by");
        profile.numberings.push_back({entry.at("name").get<std::string>(), entry.at("offset").get<int>(),
                                      selector.at("parameter").get<std::string>(),
                                      selector.at("equals").get<std::int32_t>()});
    }
    for (const Json& entry : addressing.value("mirrors", Json::array())) {
        profile.mirrors.push_back({table_from(entry.at("table")), entry.at("first").get<std::uint16_t>(),
                                   entry.at("last").get<std::uint16_t>(), entry.at("offset").get<int>()});
    }
}

void read_identification(const Json& identification, Profile& profile) {
    for (const Json& entry : identification.at("match")) {
        profile.identification.push_back({entry.at("parameter").get<std::string>(), entry.at("equals").get<std::int32_t>()});
    }
    profile.identification_report = identification.value("report", std::vector<std::string>());
}

void read_aliases(const Json& document, Profile& profile) {
    const Json aliases = document.value("aliases", Json::object());  // held: items() refers to it
    for (const auto& [alias, name] : aliases.items()) profile.aliases.emplace(alias, name.get<std::string>());
}

void read_mode_requirements(const Json& document, Profile& profile) {
    const auto requirements = document.find("mode_requirements");
    if (requirements == document.end()) return;
    for (const auto& [mode, checks] : requirements->items()) {
        for (const Json& check : checks) {
            profile.mode_requirements[mode].push_back({check.at("parameter").get<std::string>(), check.at("equals").get<std::int32_t>()});
        }
    }
}

// The checks guarantee every named bound exists.
void describe_bound_sources(const Profile& profile, Parameter& parameter) {
    for (const auto& bound : {parameter.min, parameter.max}) {
        const std::string* name = bound ? std::get_if<std::string>(&*bound) : nullptr;
        if (name == nullptr) continue;
        if (const Parameter* source = profile.find(*name)) {
            parameter.bound_sources[*name] = BoundSource{source->type, source->decimals, source->special, source->unit};
        }
    }
}

}  // namespace

Profile profile_from_document(const Json& document) {
    Profile profile;
    profile.id = document.at("id").get<std::string>();
    profile.title = document.at("title").get<std::string>();
    profile.manufacturer = document.value("manufacturer", std::string());
    profile.model = document.value("model", std::string());
    profile.manual_file = document.at("manual").at("file").get<std::string>();
    profile.manual_document = document.at("manual").at("document").get<std::string>();
    read_line(document, profile);
    read_addressing(document.at("addressing"), profile);
    if (document.contains("identification")) read_identification(document.at("identification"), profile);
    read_mode_requirements(document, profile);
    read_aliases(document, profile);
    const auto word_specials = specials_from(document.value("word_specials", Json::array()));
    for (const Json& entry : document.at("parameters")) profile.parameters.push_back(parameter_from(entry, word_specials));
    for (Parameter& parameter : profile.parameters) describe_bound_sources(profile, parameter);
    return profile;
}

}  // namespace loopwire::device
