#pragma once
// Reading a `loopwire dump` document back (restore): the profile it was taken from, the
// identification words and every parameter's raw word(s).
#include <map>
#include <string>

#include "common/result.hpp"
#include "profile/profile.hpp"
#include "profile/values.hpp"

namespace loopwire::device {

struct DumpFile {
    std::string profile;
    int unit = 0;
    std::string time;
    device::RawValues identification;  // raw words by name, where the dump gives them
    device::RawValues values;          // the first raw word of every parameter read
    std::map<std::string, std::string> texts;  // the "text" of every entry that has one, as saved
};

// Errors (ErrorKind::usage) name the file, the JSON pointer of the wrong value and what was
// expected there; every value restore uses is checked (a parameter's raw words included).
Result<DumpFile> read_dump_file(const std::string& path);
// The same from the file's text; `path` only names it in errors.
Result<DumpFile> parse_dump_text(const std::string& text, const std::string& path);

// Restore writes the raw words; a "text" that is not what its raw word reads as under `profile`
// (the dump's own) was edited, and the edit would be lost without a word: refused, naming the
// parameter and what to edit instead.
Result<void> check_texts_match_raw(const DumpFile& dump, const Profile& profile, const std::string& path);

}  // namespace loopwire::device
