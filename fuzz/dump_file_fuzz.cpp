// `loopwire restore`'s dump reader on arbitrary text. Properties: it never throws or aborts
// (nlohmann type errors included); an error is a usage error naming the file; every value it
// returns is one raw word per parameter.
#include <string>

#include "client/dump_file.hpp"
#include "fuzz_support.hpp"

using namespace loopwire;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    const auto dump = device::parse_dump_text(text, "fuzz.json");
    if (!dump.ok()) {
        fuzz::check(dump.error().kind == ErrorKind::usage, "a bad dump is a usage error");
        fuzz::check(dump.error().message.starts_with("fuzz.json: "), "a bad dump's error names the file");
        return 0;
    }
    fuzz::check(dump->unit >= 0 && dump->unit <= 255, "unit in 0..255");
    return 0;
}
