#pragma once
// What /metrics shows of the OPC UA front (gateway/opcua/opcua_server.hpp), apart from the server
// so that the metrics need no open62541.
#include <cstdint>

namespace loopwire::gateway {

struct OpcuaFigures {
    std::uint64_t sessions = 0;         // open now
    std::uint64_t monitored_items = 0;  // over every subscription, now
    std::uint64_t writes_confirmed = 0;  // since start: the device took them
    std::uint64_t writes_refused = 0;    // since start: refused, failed or not answered in time
};

}  // namespace loopwire::gateway
