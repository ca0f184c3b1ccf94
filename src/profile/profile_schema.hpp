#pragma once
// Validation of a profile document against profiles/profile.schema.json (draft-07), which is
// compiled into the library (embedded_profiles.hpp).
#include <vector>

#include <nlohmann/json.hpp>

#include "profile/json_document.hpp"

namespace loopwire::device {

// What is wrong with `document` by the schema, one problem per offending value; empty when it
// conforms. Messages say what was expected and what was found.
std::vector<DocumentProblem> schema_problems(const nlohmann::json& document);

}  // namespace loopwire::device
