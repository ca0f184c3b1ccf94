#include "profile/profile_schema.hpp"

#include <algorithm>

#include <valijson/adapters/nlohmann_json_adapter.hpp>
#include <valijson/schema.hpp>
#include <valijson/schema_parser.hpp>
#include <valijson/validation_results.hpp>
#include <valijson/validator.hpp>

#include "profile/embedded_profiles.hpp"
#include "profile/schema_messages.hpp"

namespace loopwire::device {
namespace {

using Json = nlohmann::json;

// The embedded schema, parsed once. It is part of the build, so a schema valijson cannot read
// is a defect of the build (valijson throws; VALIJSON_USE_EXCEPTIONS is set for this library).
class CompiledSchema {
public:
    CompiledSchema() : document(Json::parse(embedded_schema_text())) {
        valijson::SchemaParser parser(valijson::SchemaParser::kDraft7);
        const valijson::adapters::NlohmannJsonAdapter adapter(document);
        parser.populateSchema(adapter, schema);
    }
    const Json document;
    valijson::Schema schema;
};

const CompiledSchema& compiled_schema() {
    static const CompiledSchema compiled;  // thread-safe initialisation (C++11 magic statics)
    return compiled;
}

struct Violation {
    std::vector<std::string> tokens;
    std::string message;
};

// valijson names the path "<root>", "[parameters]", "[12]", "[access]".
std::vector<std::string> path_tokens(const std::vector<std::string>& context) {
    std::vector<std::string> tokens;
    for (const std::string& element : context) {
        if (element == "<root>") continue;
        const bool bracketed = element.size() >= 2 && element.front() == '[' && element.back() == ']';
        tokens.push_back(bracketed ? element.substr(1, element.size() - 2) : element);
    }
    return tokens;
}

// Messages that only say "something below failed"; the failure below is reported instead.
bool is_summary(const std::string& description) {
    for (const char* prefix : {"Failed to validate item #", "Failed to validate against schema associated with",
                               "Failed to validate against additional properties schema",
                               "Failed to validate against child schema #", "Cannot validate item #"}) {
        if (description.rfind(prefix, 0) == 0) return true;
    }
    return false;
}

bool is_one_of_failure(const std::string& description) {
    return description.find("allowed by oneOf constraint") != std::string::npos;
}

bool starts_with(const std::vector<std::string>& tokens, const std::vector<std::string>& prefix) {
    return tokens.size() >= prefix.size() && std::equal(prefix.begin(), prefix.end(), tokens.begin());
}

const Json* value_at(const Json& document, const std::vector<std::string>& tokens) {
    const Json::json_pointer pointer(json_pointer_text(tokens));
    return document.contains(pointer) ? &document.at(pointer) : nullptr;
}

std::vector<Violation> violations(const Json& document, const valijson::ValidationResults& results) {
    const CompiledSchema& schema = compiled_schema();
    std::vector<Violation> found;
    for (const auto& error : results) {
        if (is_summary(error.description)) continue;
        std::vector<std::string> tokens = path_tokens(error.context);
        const auto schemas = schemas_at(schema.document, document, tokens);
        const Json* value = value_at(document, tokens);
        if (is_one_of_failure(error.description)) {
            // valijson reports each alternative's failure just before the oneOf failure; one
            // message naming every alternative says more than those put together.
            while (!found.empty() && starts_with(found.back().tokens, tokens)) found.pop_back();
            found.push_back({std::move(tokens), one_of_message(schema.document, schemas, value)});
            continue;
        }
        found.push_back({std::move(tokens), schema_violation_message(error.description, schemas, value)});
    }
    return found;
}

}  // namespace

std::vector<DocumentProblem> schema_problems(const Json& document) {
    valijson::Validator validator(valijson::Validator::kStrongTypes);
    valijson::ValidationResults results;
    const valijson::adapters::NlohmannJsonAdapter target(document);
    if (validator.validate(compiled_schema().schema, target, &results)) return {};

    std::vector<DocumentProblem> problems;
    for (const Violation& violation : violations(document, results)) {
        DocumentProblem problem{json_pointer_text(violation.tokens), violation.message};
        const bool repeated = std::any_of(problems.begin(), problems.end(), [&](const DocumentProblem& seen) {
            return seen.pointer == problem.pointer && seen.message == problem.message;
        });
        if (!repeated) problems.push_back(std::move(problem));
    }
    if (problems.empty()) problems.push_back({"", "does not match profiles/profile.schema.json"});
    return problems;
}

}  // namespace loopwire::device
