#pragma once
// The profile schema and the built-in profiles, compiled into the library at build time
// (embed_profiles.cmake) so loopwire runs from any directory without profiles/ beside it.
#include <span>
#include <string_view>

namespace loopwire::device {

struct EmbeddedProfileText {
    std::string_view id;      // "ac20"
    std::string_view origin;  // "profiles/ac20.json": what error messages name
    std::string_view text;
};

std::string_view embedded_schema_text();
std::span<const EmbeddedProfileText> embedded_profile_texts();

}  // namespace loopwire::device
