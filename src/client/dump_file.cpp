#include "client/dump_file.hpp"

#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace loopwire::device {
namespace {

Error bad_dump(const std::string& path, const std::string& what) {
    return make_error(ErrorKind::usage, fmt::format("{}: {}; give a file written by `loopwire dump`", path, what));
}

// "raw": 150, or [150] (a parameter's words); null when the parameter could not be read.
std::optional<std::uint16_t> first_raw(const nlohmann::json& entry) {
    const nlohmann::json* raw = entry.is_object() && entry.contains("raw") ? &entry["raw"] : &entry;
    if (raw->is_array() && !raw->empty()) raw = &(*raw)[0];
    if (!raw->is_number_integer()) return std::nullopt;
    const auto number = raw->get<long long>();
    if (number < 0 || number > 0xFFFF) return std::nullopt;
    return static_cast<std::uint16_t>(number);
}

}  // namespace

Result<DumpFile> read_dump_file(const std::string& path) {
    std::ifstream file(path, std::ios::binary);
    if (!file) return make_error(ErrorKind::usage, fmt::format("cannot read {}: no such file or no permission", path));
    std::ostringstream text;
    text << file.rdbuf();
    const auto document = nlohmann::json::parse(text.str(), nullptr, false);
    if (document.is_discarded()) return bad_dump(path, "is not valid JSON");
    if (!document.is_object() || document.value("format", "") != "loopwire-dump") return bad_dump(path, "is not a loopwire dump (no \"format\": \"loopwire-dump\")");
    if (document.value("version", 0) != 1) return bad_dump(path, "has a dump format version this loopwire does not know (expected 1)");
    if (!document.contains("profile") || !document["profile"].is_string()) return bad_dump(path, "names no profile");
    if (!document.contains("parameters") || !document["parameters"].is_object()) return bad_dump(path, "has no \"parameters\" object");
    DumpFile dump;
    dump.profile = document["profile"].get<std::string>();
    dump.unit = document.value("unit", 0);
    dump.time = document.value("time", "");
    for (const auto& [name, entry] : document["parameters"].items()) {
        if (const auto raw = first_raw(entry)) dump.values.emplace(name, *raw);
    }
    if (document.contains("identification") && document["identification"].is_object()) {
        for (const auto& [name, entry] : document["identification"].items()) {
            if (const auto raw = first_raw(entry)) dump.identification.emplace(name, *raw);
        }
    }
    return dump;
}

}  // namespace loopwire::device
