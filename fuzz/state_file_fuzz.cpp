// `loopwire simulate --state`'s reader on arbitrary text. Properties: it never throws or
// aborts; an error is a usage error naming the file; an accepted document has the shapes the
// simulator then uses without further checks (SimulatorStateFile::load).
#include <string>

#include "simulation/state_file.hpp"
#include "common/json_checks.hpp"
#include "fuzz_support.hpp"

using namespace loopwire;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    const auto document = device::parse_state_text(text, "fuzz.json");
    if (!document.ok()) {
        fuzz::check(document.error().kind == ErrorKind::usage, "a bad state file is a usage error");
        fuzz::check(document.error().message.starts_with("fuzz.json: "), "a bad state file's error names the file");
        return 0;
    }
    fuzz::check(document->at("units").is_object(), "units is an object");
    for (const auto& [unit, entry] : document->at("units").items()) {
        fuzz::check(entry.at("profile").is_string(), "each unit names its profile");
        for (const auto& [name, raw] : entry.at("saved").items()) fuzz::check(json_word(raw).has_value(), "saved values are words");
    }
    return 0;
}
