#pragma once
// Checks beyond profiles/profile.schema.json, which validates one value at a time and cannot
// relate entries to each other. Run on a document that already conforms to the schema.
//
//  - parameter names are unique;
//  - (table, address) pairs are unique, except where both entries carry a non-empty "note":
//    two entries at one address only happen through a manual glitch (a row printed twice, two
//    editions disagreeing), and the note is where that glitch must be explained;
//  - every reference names an existing parameter: decimals and range bounds
//    ({"parameter": X}), identification match and report, numbering selectors; a parameter
//    cannot take its own decimals or bounds from itself;
//  - write_modes name modes of the top-level "modes";
//  - bool entries, and only they, live in the bit tables (coils, discrete);
//  - enum keys fit a 16-bit word (-32768..65535); fixed ranges have min <= max;
//  - a number (int16/uint16) has exactly one of a non-empty "unit", "unit_from" (whose
//    words exist) or "unitless"; enums, bit fields and bools have neither of the last two;
//    unit_from keys fit a 16-bit word;
//  - unit_ids are whole numbers 1 <= min <= max <= 255;
//  - identification matches and numbering selectors give "equals";
//  - exception codes are 1..255; mirrored ranges stay within 0..65535.
#include <vector>

#include <nlohmann/json.hpp>

#include "profile/json_document.hpp"

namespace loopwire::device {

std::vector<DocumentProblem> semantic_problems(const nlohmann::json& document);

}  // namespace loopwire::device
