#pragma once
// Reading a `loopwire dump` document back (restore): the profile it was taken from, the
// identification words and every parameter's raw word(s).
#include <map>
#include <string>

#include "common/result.hpp"
#include "profile/values.hpp"

namespace loopwire::device {

struct DumpFile {
    std::string profile;
    int unit = 0;
    std::string time;
    device::RawValues identification;  // raw words by name, where the dump gives them
    device::RawValues values;          // the first raw word of every parameter read
};

// Errors (ErrorKind::usage) name the file, the JSON pointer of the wrong value and what was
// expected there; every value restore uses is checked (a parameter's raw words included).
Result<DumpFile> read_dump_file(const std::string& path);
// The same from the file's text; `path` only names it in errors.
Result<DumpFile> parse_dump_text(const std::string& text, const std::string& path);

}  // namespace loopwire::device
