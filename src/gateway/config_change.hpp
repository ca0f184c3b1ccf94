#pragma once
// What a reload of the configuration changed, in words, for the audit (gateway/write_audit.hpp):
// "line furnace added (2 devices); device oven removed from line kiln; [mqtt] changed". A person
// reading the audit learns what was touched; the file itself says how.
#include <string>

#include "gateway/gateway_config.hpp"
#include "gateway/write_audit.hpp"

namespace loopwire::gateway {

// The lines and devices added, removed or changed (by name), then each front or table ([gateway]
// name, [modbus_tcp], [mqtt], [sparkplug], [http], [history], [log]) added, removed or changed,
// joined by "; "; "nothing changed" when the two are alike.
std::string describe_config_change(const GatewayConfig& before, const GatewayConfig& after);

// The audit's record of a reload asked for by `who` ("SIGHUP") of the configuration `file`:
// front "reload", parameter "configuration", the change as its new value; confirmed, or
// refused with the reason (the file does not load, the gateway it asks for cannot be opened),
// its lines joined by "; ".
AuditRecord reload_record(const std::string& who, const std::string& file, std::string change, std::string outcome);

}  // namespace loopwire::gateway
