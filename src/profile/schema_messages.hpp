#pragma once
// Readable messages for schema violations. valijson reports "Failed to match against any enum
// values." without the values; these helpers look the constraint up in the schema itself so a
// message can say "must be one of r, w, rw (found \"x\")".
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace loopwire::device {

// The subschemas that constrain the value at `tokens` (reference tokens of an instance path),
// with $ref followed and oneOf/anyOf/allOf alternatives expanded.
std::vector<const nlohmann::json*> schemas_at(const nlohmann::json& schema, const nlohmann::json& document,
                                              const std::vector<std::string>& tokens);

// One violation, as valijson describes it, rewritten for people. `value` is the offending value
// (nullptr when the path does not exist in the document).
std::string schema_violation_message(const std::string& valijson_description,
                                     const std::vector<const nlohmann::json*>& schemas,
                                     const nlohmann::json* value);

// "oneOf" failures: what each alternative would accept.
std::string one_of_message(const nlohmann::json& schema, const std::vector<const nlohmann::json*>& schemas,
                           const nlohmann::json* value);

}  // namespace loopwire::device
