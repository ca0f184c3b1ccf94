// A gateway built without open62541 (LOOPWIRE_OPCUA off): [opcua] is refused at start, saying why.
#include "gateway/opcua/opcua_server.hpp"

namespace loopwire::gateway {

struct OpcuaServer::State {};

OpcuaServer::OpcuaServer(std::unique_ptr<State> state) : state_(std::move(state)) {}
OpcuaServer::~OpcuaServer() = default;

Result<std::unique_ptr<OpcuaServer>> OpcuaServer::open(const OpcuaConfig&, const std::string&, std::vector<OpcuaDevice>,
                                                       const DeviceWriter&, ValueCache&, GatewayLog) {
    return make_error(ErrorKind::usage,
                      "[opcua]: this loopwire was built without the OPC UA front (open62541 1.4 was not found); "
                      "install libopen62541-1.4-dev (scripts/setup) and build again, or remove [opcua]");
}

std::uint16_t OpcuaServer::port() const { return 0; }
std::string OpcuaServer::endpoint() const { return {}; }
OpcuaFigures OpcuaServer::figures() const { return {}; }

}  // namespace loopwire::gateway
