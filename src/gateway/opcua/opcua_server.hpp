#pragma once
// The gateway's OPC UA front (open62541 1.4): every polled parameter a variable
// ns=1;s=DEVICE.PARAMETER under Objects/GATEWAY/LINE/DEVICE, with a Status variable per device;
// scaled values are AnalogItemType (Double) with EURange and EngineeringUnits, whole words Int16
// or UInt16 (opcua_nodes.hpp). Statuses are mapped once (opcua_status.hpp).
//
// Threads: open62541 runs on a thread of its own (lw-opcua), not iterated from the engine's loop.
// The reason is the Write service: open62541 1.4 answers a Write from a synchronous callback (its
// asynchronous operations cover method calls only), and a write must be answered with what the
// device said. On the engine's loop that callback could not wait for the line without stopping
// the loop; on its own thread it hands the write to the device's line (DeviceWriter::write_async)
// and waits for the completion, which the loop delivers. While a write waits, this front alone
// waits (its other clients with it); the lines and the other fronts never do.
// Values come the other way through a queue: the value cache's callback only copies each change
// into it (never touching open62541), and the front's thread applies them between its iterations.
// Nothing in the lines or the cache ever waits for open62541.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "gateway/device_writer.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/gateway_config.hpp"
#include "gateway/opcua/opcua_figures.hpp"
#include "gateway/value_cache.hpp"

namespace loopwire::gateway {

// A device of the address space: its configured name, the parameters its polls read, its line.
struct OpcuaDevice {
    std::string name;
    std::string line;
    std::vector<const device::Parameter*> parameters;
};

class OpcuaServer {
public:
    // Builds the address space and starts listening; the error names an endpoint that cannot be
    // opened, or a gateway built without the front. `writer` and `cache` must outlive the server.
    static Result<std::unique_ptr<OpcuaServer>> open(const OpcuaConfig& config, const std::string& gateway_name,
                                                     std::vector<OpcuaDevice> devices, const DeviceWriter& writer,
                                                     ValueCache& cache, GatewayLog log);
    // Stops listening; a write under way is answered first.
    ~OpcuaServer();
    OpcuaServer(const OpcuaServer&) = delete;
    OpcuaServer& operator=(const OpcuaServer&) = delete;

    std::uint16_t port() const;  // the one the kernel chose for port 0
    std::string endpoint() const;  // "opc.tcp://127.0.0.1:PORT"
    OpcuaFigures figures() const;  // any thread

    struct State;

private:
    explicit OpcuaServer(std::unique_ptr<State> state);
    std::unique_ptr<State> state_;
};

}  // namespace loopwire::gateway
