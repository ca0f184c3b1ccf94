#pragma once
// `loopwire read/write --device DEVICE@UNIT NAME...`: parameter names in, engineering values out.
#include <string>
#include <vector>

#include "app/master_options.hpp"

namespace loopwire::app {

int run_device_read(const MasterCommandOptions& options, const std::vector<std::string>& names);
int run_device_write(const MasterCommandOptions& options, const std::vector<std::string>& assignments);

}  // namespace loopwire::app
