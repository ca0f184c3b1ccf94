#include "client/scan_config.hpp"

#include <algorithm>
#include <map>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

// A TOML basic string: quotes and backslashes escaped, control bytes as \uXXXX.
std::string quoted(const std::string& text) {
    std::string out = "\"";
    for (const char c : text) {
        if (c == '"' || c == '\\') {
            out += '\\';
            out += c;
        } else if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) {
            out += fmt::format("\\u{:04X}", static_cast<unsigned char>(c));
        } else {
            out += c;
        }
    }
    return out + "\"";
}

// "VendorName \"x\", ProductCode \"y\"": what a unit said of itself, for a comment (one line).
std::string identity_text(const FoundUnit& unit) {
    if (!unit.device_identity.is_object() || unit.device_identity.empty()) return "";
    std::vector<std::string> parts;
    for (const auto& [name, value] : unit.device_identity.items()) parts.push_back(fmt::format("{} {}", name, value.dump()));
    return fmt::format(" ({})", fmt::join(parts, ", "));
}

// The setting most identified units answered at (the first tried among equals); the scan's
// first setting when none was identified.
std::size_t chosen_setting(const std::vector<std::string>& settings_text, const std::vector<FoundUnit>& found) {
    std::map<std::size_t, int> identified_at;
    for (const auto& unit : found) {
        if (unit.device.empty()) continue;
        const auto at = std::find(settings_text.begin(), settings_text.end(), unit.line);
        if (at != settings_text.end()) ++identified_at[static_cast<std::size_t>(at - settings_text.begin())];
    }
    std::size_t best = 0;
    int most = 0;
    for (const auto& [index, count] : identified_at) {
        if (count > most) {
            best = index;
            most = count;
        }
    }
    return best;
}

bool answered_at(const FoundUnit& unit, const std::string& line) {
    return std::find(unit.lines.begin(), unit.lines.end(), line) != unit.lines.end();
}

}  // namespace

std::string scan_configuration(const UnitScan& scan, const std::vector<FoundUnit>& found) {
    const std::vector<std::string> settings_text = scan.settings_text();
    const std::size_t chosen = chosen_setting(settings_text, found);
    const transport::LinkUrl& link = scan.settings().at(chosen);
    const std::string& line = settings_text.at(chosen);
    std::string out = fmt::format(
        "# Written by `loopwire scan --emit-config`: the units that answered on {}.\n"
        "# Name the line and devices as you like, then check it: loopwire gateway --config FILE --check\n\n",
        link.to_string());
    out += fmt::format("[[lines]]\nname = \"scanned\"\nlink = {}\n", quoted(link.to_string()));
    std::string comments;
    for (const auto& unit : found) {
        if (!answered_at(unit, line)) {
            comments += fmt::format("# unit {} ({}) answered at {} only, not at this line's {}: one port is one line, so "
                                    "set the unit to {} to add it here\n",
                                    unit.unit, unit.device.empty() ? "not identified" : unit.device, fmt::join(unit.lines, ", "),
                                    line, line);
        } else if (unit.device.empty()) {
            comments += fmt::format("# unit {} answered but matches no profile loopwire knows{}: add a profile "
                                    "(--profile FILE.json) to poll it\n",
                                    unit.unit, identity_text(unit));
        } else {
            out += fmt::format("\n[[lines.devices]]\nname = \"{}-{}\"\ndevice = \"{}@{}\"\n", unit.device, unit.unit, unit.device,
                               unit.unit);
            if (!unit.device_identity.is_null()) out += fmt::format("# it says of itself{}\n", identity_text(unit));
        }
    }
    if (!comments.empty()) out += "\n" + comments;
    return out;
}

}  // namespace loopwire::device
