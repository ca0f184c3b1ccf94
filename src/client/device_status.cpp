#include "client/device_status.hpp"

#include <ostream>

namespace loopwire::device {

std::optional<DeviceStatus> parse_device_status(std::string_view text) {
    for (const DeviceStatus status : all_device_statuses) {
        if (status_text(status) == text) return status;
    }
    return std::nullopt;
}

std::ostream& operator<<(std::ostream& out, DeviceStatus status) { return out << status_text(status); }

}  // namespace loopwire::device
