#pragma once
// `loopwire read/write --device DEVICE@UNIT NAME...`: parameter names in, engineering values out.
#include <string>
#include <vector>

#include "app/master_options.hpp"
#include "profile/profile_registry.hpp"

namespace loopwire::app {

int run_device_read(const device::ProfileRegistry& profiles, const MasterCommandOptions& options, const std::vector<std::string>& names);
int run_device_write(const device::ProfileRegistry& profiles, const MasterCommandOptions& options, const std::vector<std::string>& assignments);

}  // namespace loopwire::app
