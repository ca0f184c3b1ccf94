#pragma once
// Which parameters `loopwire monitor` watches on each device.
#include <string>
#include <vector>

#include "common/result.hpp"
#include "client/device_client.hpp"

namespace loopwire::device {

// The default watch list of a profile, used for a device no NAME applies to: the process
// value, the set point (and the one in force), the control output, the alarm state and mode. For the built-in
// profiles these are listed by name (monitor_names.cpp); for any other profile, its first four
// readable, not hidden parameters.
std::vector<const device::Parameter*> default_watch_list(const device::Profile& profile);

// NAMES as given on the command line, to a watch list per device (same order as `devices`):
//   NAME               every device (a name, mnemonic, group or "all", as in `loopwire read`);
//                      an error, naming the device, when it matches nothing on one of them
//   DEVICE@UNIT:NAME   only that device (an error when it is not one of `devices`)
// A device no NAME applies to gets default_watch_list.
Result<std::vector<std::vector<const device::Parameter*>>> watch_lists(const std::vector<device::DeviceAddress>& devices,
                                                                       const std::vector<std::string>& names);

}  // namespace loopwire::device
