#pragma once
// `loopwire scan --emit-config FILE`: a gateway configuration (loopwire-gateway.toml(5)) of
// what a scan found, for `loopwire gateway --config FILE --check` and then to run.
#include <string>
#include <vector>

#include "client/scan.hpp"

namespace loopwire::device {

// One [[lines]] table on the link at the setting where most identified units answered, a
// [[lines.devices]] table per unit identified there ("tc10@3", named "tc10-3"), and comments
// for the units found but not identified and for those that answered at another setting only
// (one port is one line). `found` is what `scan` found.
std::string scan_configuration(const UnitScan& scan, const std::vector<FoundUnit>& found);

}  // namespace loopwire::device
