// The profile loader (schema, checks, conversion) on arbitrary text. Properties: it never
// throws or aborts; an error is a usage error naming the origin; and no input reaches the
// conversion's last-resort catch (a type the schema should have refused): such an input is a
// gap in profile.schema.json to close.
#include <string>

#include "profile/profile.hpp"
#include "fuzz_support.hpp"

using namespace loopwire;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    const auto profile = device::load_profile_text(text, "fuzz.json");
    if (!profile.ok()) {
        fuzz::check(profile.error().kind == ErrorKind::usage, "a bad profile is a usage error");
        fuzz::check(profile.error().message.find("fuzz.json") != std::string::npos, "a bad profile's error names the file");
        // A syntax error quotes the input around it: an input holding the phrase itself can
        // bring it into the message without any gap in the schema.
        if (text.find(device::profile_type_gap_message) == std::string::npos) {
            fuzz::check(profile.error().message.find(device::profile_type_gap_message) == std::string::npos,
                        "the schema refuses every type the conversion cannot use");
        }
        return 0;
    }
    fuzz::check(!profile->id.empty(), "a loaded profile has an id");
    return 0;
}
