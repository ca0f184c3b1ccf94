#pragma once
// A device the gateway has no profile for, described in its configuration by its points
// ([[lines.devices.points]]: name, table, address, type, ...). The points are written as the JSON
// profile document they stand for and loaded by the profile loader, so such a device has the
// same model a profile file gives and every front serves it as it serves any other;
// `loopwire profile from-points` prints that document.
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <toml++/toml.h>

#include "common/result.hpp"

namespace loopwire::gateway {

struct PointsProfile {
    nlohmann::json document;          // the profile, as a profile file holds it
    std::vector<std::string> polled;  // the points polled: all but those with poll = false
};

// The profile of the device `table` (a [[lines.devices]] table with points) named
// `device_name`, at `path` ("lines[0].devices[1]") of the file `source`. Every mistake is
// appended to `mistakes` as "FILE:LINE: KEY.PATH: what, and the fix"; none is returned when there
// was any.
std::optional<PointsProfile> points_profile(const toml::table& table, const std::string& source, const std::string& path,
                                            const std::string& device_name, std::vector<Error>& mistakes);

// `loopwire profile from-points FILE DEVICE`: the profile of the device named `device_name` in
// the gateway configuration `file`, as JSON text a profile file can hold.
Result<std::string> points_profile_text(const std::filesystem::path& file, const std::string& device_name);

}  // namespace loopwire::gateway
