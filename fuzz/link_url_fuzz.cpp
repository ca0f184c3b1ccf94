// Link URL parser on arbitrary text. Properties: errors are usage errors with a message;
// a parsed URL prints as a string that parses back to the same printed form.
#include <string_view>

#include "fuzz_support.hpp"
#include "transport/link_url.hpp"

using namespace loopwire;
using namespace loopwire::transport;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    const auto url = parse_link_url(text);
    if (!url.ok()) {
        fuzz::check(url.error().kind == ErrorKind::usage, "link URL error is a usage error");
        fuzz::check(!url.error().message.empty(), "link URL error has a message");
        return 0;
    }
    fuzz::check(!framing_name(url->framing).empty(), "framing has a name");
    const std::string printed = url->to_string();
    const auto again = parse_link_url(printed);
    fuzz::check(again.ok(), "a printed link URL parses");
    fuzz::check(again->to_string() == printed, "a printed link URL prints the same");
    return 0;
}
