#pragma once
// "tc10@3" or "path/to/profile.json@3": the device a caller of the public API names.
#include <string>

#include "client/device_client.hpp"
#include "common/result.hpp"

namespace loopwire::api {

// A name with a '/' or ending in ".json" before the '@' is a profile file, loaded and checked
// like the built-in ones; anything else is a built-in profile id. The unit after '@' is
// within the profile's unit_ids (1..255 at most), and 1 when there is no '@'.
Result<device::DeviceAddress> resolve_device(const std::string& text);

}  // namespace loopwire::api
