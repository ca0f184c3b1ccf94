#include "api/device_spec.hpp"

#include <memory>

#include <fmt/format.h>

#include "common/text_parsing.hpp"
#include "profile/profile.hpp"

namespace loopwire::api {
namespace {

bool names_a_file(const std::string& profile) {
    return profile.find('/') != std::string::npos ||
           (profile.size() > 5 && profile.compare(profile.size() - 5, 5, ".json") == 0);
}

}  // namespace

Result<device::DeviceAddress> resolve_device(const std::string& text) {
    // The last '@': a file's path may hold one, a unit id never does.
    const auto at = text.rfind('@');
    const std::string profile_name = text.substr(0, at);
    if (!names_a_file(profile_name)) return device::parse_device_address(text);
    auto loaded = device::load_profile_file(profile_name);
    if (!loaded) return loaded.error();
    device::DeviceAddress address{std::make_shared<const device::Profile>(std::move(*loaded)), 1, 0};
    if (at != std::string::npos) {
        auto unit = parse_integer(text.substr(at + 1), address.profile->first_unit, address.profile->last_unit, fmt::format("the unit after '@' in '{}'", text));
        if (!unit) return unit.error();
        address.unit = static_cast<std::uint8_t>(*unit);
    }
    return address;
}

}  // namespace loopwire::api
