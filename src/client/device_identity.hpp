#pragma once
// Reading what a unit says it is through Read Device Identification (function 43, MEI type 14),
// for `loopwire scan` and `loopwire describe --link`.
#include <cstdint>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "codec/device_identification.hpp"
#include "common/result.hpp"
#include "session/master.hpp"

namespace loopwire::device {

// The unit's basic objects (VendorName, ProductCode, MajorMinorRevision), and its regular ones
// where its conformity level says it has them, each stream followed while more follows.
// nullopt: the unit does not implement it (exception 01h, illegal function, or 02h/03h for the
// category asked). Other failures (no reply, a malformed reply) are errors.
Result<std::optional<std::vector<codec::IdentificationObject>>> read_device_identity(session::Master& master, std::uint8_t unit);

// {"VendorName": "...", "ProductCode": "...", ...} in the order the unit sent them.
nlohmann::ordered_json identity_json(const std::vector<codec::IdentificationObject>& objects);

}  // namespace loopwire::device
