#include "profile/schema_messages.hpp"

#include <regex>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

using Json = nlohmann::json;

// Deep enough for this schema ($ref -> oneOf -> $ref); a guard against reference cycles.
constexpr int max_expansion_depth = 16;

const Json* resolve_reference(const Json& root, const Json* schema) {
    for (int depth = 0; schema != nullptr && depth < max_expansion_depth; ++depth) {
        const auto ref = schema->find("$ref");
        if (ref == schema->end() || !ref->is_string()) return schema;
        const std::string target = ref->get<std::string>();
        if (target.empty() || target[0] != '#') return nullptr;  // only local references here
        const Json::json_pointer pointer(target.substr(1));
        schema = root.contains(pointer) ? &root.at(pointer) : nullptr;
    }
    return schema;
}

void expand(const Json& root, const Json* schema, std::vector<const Json*>& out, int depth) {
    schema = resolve_reference(root, schema);
    if (schema == nullptr || !schema->is_object() || depth > max_expansion_depth) return;
    out.push_back(schema);
    for (const char* combinator : {"oneOf", "anyOf", "allOf"}) {
        const auto alternatives = schema->find(combinator);
        if (alternatives == schema->end() || !alternatives->is_array()) continue;
        for (const Json& alternative : *alternatives) expand(root, &alternative, out, depth + 1);
    }
}

// The subschemas a member `name` of an object is checked against (properties, else matching
// patternProperties, else additionalProperties), as draft-07 §6.5.4–6.5.6 define.
void member_schemas(const Json& schema, const std::string& name, std::vector<const Json*>& out) {
    if (const auto properties = schema.find("properties");
        properties != schema.end() && properties->contains(name)) {
        out.push_back(&properties->at(name));
        return;
    }
    bool matched = false;
    if (const auto patterns = schema.find("patternProperties"); patterns != schema.end()) {
        for (const auto& [pattern, subschema] : patterns->items()) {
            if (std::regex_search(name, std::regex(pattern))) {
                out.push_back(&subschema);
                matched = true;
            }
        }
    }
    if (const auto additional = schema.find("additionalProperties");
        !matched && additional != schema.end() && additional->is_object()) {
        out.push_back(&*additional);
    }
}

const Json* child_of(const Json* value, const std::string& token) {
    if (value == nullptr) return nullptr;
    if (value->is_object()) {
        const auto member = value->find(token);
        return member == value->end() ? nullptr : &*member;
    }
    if (value->is_array()) {
        const std::size_t index = std::stoul(token);
        return index < value->size() ? &(*value)[index] : nullptr;
    }
    return nullptr;
}

std::string plain(const Json& value) {
    return value.is_string() ? value.get<std::string>() : value.dump();
}

std::string found_text(const Json* value, bool with_type) {
    if (value == nullptr) return {};
    std::string text = value->dump();
    constexpr std::size_t longest = 60;
    if (text.size() > longest) text = text.substr(0, longest) + "...";
    return with_type ? fmt::format(" (found {} {})", value->type_name(), text) : fmt::format(" (found {})", text);
}

const Json* first_with(const std::vector<const Json*>& schemas, const char* keyword) {
    for (const Json* schema : schemas) {
        if (schema->contains(keyword)) return schema;
    }
    return nullptr;
}

std::string joined(const Json& values, const char* separator) {
    std::string text;
    for (const Json& value : values) {
        if (!text.empty()) text += separator;
        text += plain(value);
    }
    return text;
}

std::string type_text(const Json& schema) {
    const Json& type = schema.at("type");
    return type.is_array() ? joined(type, " or ") : plain(type);
}

// "integer 0..4", "object with \"parameter\"", "one of a, b": what one alternative accepts.
std::string accepted_by(const Json& schema) {
    if (schema.contains("enum")) return "one of " + joined(schema.at("enum"), ", ");
    if (!schema.contains("type")) return "a value of another form";
    std::string text = type_text(schema);
    if (schema.contains("minimum") || schema.contains("maximum")) {
        text += fmt::format(" {}..{}", schema.contains("minimum") ? schema.at("minimum").dump() : "",
                            schema.contains("maximum") ? schema.at("maximum").dump() : "");
    }
    if (schema.contains("required")) text += " with " + joined(schema.at("required"), ", ");
    return text;
}

std::string quoted_between(const std::string& text, const std::string& before) {
    const auto start = text.find(before);
    if (start == std::string::npos) return {};
    const auto first = start + before.size();
    const auto last = text.find('\'', first);
    return text.substr(first, last == std::string::npos ? std::string::npos : last - first);
}

bool contains(const std::string& text, const char* part) { return text.find(part) != std::string::npos; }

std::string unknown_property_message(const std::string& name, const std::vector<const Json*>& schemas) {
    if (const Json* schema = first_with(schemas, "patternProperties"); schema != nullptr && !schema->contains("properties")) {
        std::string patterns;
        for (const auto& [pattern, unused] : schema->at("patternProperties").items()) {
            patterns += (patterns.empty() ? "" : " or ") + pattern;
        }
        return fmt::format("key \"{}\" is not allowed: keys must match {}", name, patterns);
    }
    std::string allowed;
    if (const Json* schema = first_with(schemas, "properties")) {
        for (const auto& [key, unused] : schema->at("properties").items()) {
            allowed += (allowed.empty() ? "" : ", ") + key;
        }
    }
    return allowed.empty() ? fmt::format("unknown property \"{}\"", name)
                           : fmt::format("unknown property \"{}\" (allowed: {})", name, allowed);
}

std::string bound_message(const char* keyword, const char* wording, const std::string& description,
                          const std::vector<const Json*>& schemas, const Json* value) {
    const Json* schema = first_with(schemas, keyword);
    if (schema == nullptr) return description;
    return fmt::format("must be {} {}{}", wording, schema->at(keyword).dump(), found_text(value, false));
}

}  // namespace

std::vector<const Json*> schemas_at(const Json& schema, const Json& document, const std::vector<std::string>& tokens) {
    std::vector<const Json*> current;
    expand(schema, &schema, current, 0);
    const Json* value = &document;
    for (const std::string& token : tokens) {
        std::vector<const Json*> next;
        for (const Json* candidate : current) {
            if (value != nullptr && value->is_array()) {
                if (const auto items = candidate->find("items"); items != candidate->end() && items->is_object()) {
                    next.push_back(&*items);
                }
            } else {
                member_schemas(*candidate, token, next);
            }
        }
        current.clear();
        for (const Json* candidate : next) expand(schema, candidate, current, 0);
        value = child_of(value, token);
    }
    return current;
}

std::string schema_violation_message(const std::string& description, const std::vector<const Json*>& schemas,
                                     const Json* value) {
    if (contains(description, "Missing required property")) {
        return fmt::format("missing required property \"{}\"", quoted_between(description, "property '"));
    }
    if (contains(description, "could not be validated using 'properties' or 'additionalProperties'")) {
        return unknown_property_message(quoted_between(description, "constraints: '"), schemas);
    }
    if (contains(description, "any enum values")) {
        const Json* schema = first_with(schemas, "enum");
        if (schema == nullptr) return "is not one of the allowed values";
        return fmt::format("must be one of {}{}", joined(schema->at("enum"), ", "), found_text(value, false));
    }
    if (contains(description, "'type' constraint")) {
        const Json* schema = first_with(schemas, "type");
        if (schema == nullptr) return "has the wrong type";
        return fmt::format("must be {}{}", type_text(*schema), found_text(value, true));
    }
    if (contains(description, "'pattern' constraint")) {
        const Json* schema = first_with(schemas, "pattern");
        if (schema == nullptr) return "does not match the required pattern";
        return fmt::format("must match {}{}", plain(schema->at("pattern")), found_text(value, false));
    }
    if (contains(description, "less than or equal to")) {
        return bound_message("maximum", "at most", description, schemas, value);
    }
    if (contains(description, "greater than or equal to")) {
        return bound_message("minimum", "at least", description, schemas, value);
    }
    if (contains(description, "no fewer than") && contains(description, "characters")) return "must not be empty";
    if (contains(description, "no fewer than") && contains(description, "elements")) {
        const Json* schema = first_with(schemas, "minItems");
        return schema == nullptr ? description : fmt::format("must have at least {} item(s)", schema->at("minItems").dump());
    }
    if (contains(description, "violate uniqueness constraint")) {
        // "Elements at indexes #0 and #1 violate uniqueness constraint."
        const auto first = description.find('#');
        const auto last = description.find(" violate");
        return fmt::format("items must be unique ({} are equal)", description.substr(first, last - first));
    }
    std::string text = description;
    if (!text.empty() && text.back() == '.') text.pop_back();
    return text;
}

std::string one_of_message(const Json& schema, const std::vector<const Json*>& schemas, const Json* value) {
    const Json* parent = first_with(schemas, "oneOf");
    if (parent == nullptr) return "matches none of the allowed forms";
    std::string accepted;
    for (const Json& alternative : parent->at("oneOf")) {
        // Alternatives may themselves be references; take the schema they point to.
        std::vector<const Json*> resolved;
        expand(schema, &alternative, resolved, 0);
        const Json& shown = resolved.empty() ? alternative : *resolved.front();
        accepted += (accepted.empty() ? "" : ", or ") + accepted_by(shown);
    }
    return fmt::format("must be {}{}", accepted, found_text(value, true));
}

}  // namespace loopwire::device
