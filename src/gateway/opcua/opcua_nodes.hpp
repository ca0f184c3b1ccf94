#pragma once
// The OPC UA front's address space (opcua_server.hpp): the folders Objects/GATEWAY/LINE/DEVICE,
// one variable a polled parameter and one Status variable a device, and what each shows now.
// Used on the front's thread only.
#include <chrono>
#include <optional>
#include <string>

#include <open62541/server.h>

#include "client/device_status.hpp"
#include "gateway/opcua/opcua_status.hpp"
#include "profile/values.hpp"

namespace loopwire::gateway {

// One parameter's variable, ns=1;s=DEVICE.PARAMETER, and the value it shows: the node's
// context, read by its data source.
struct OpcuaVariable {
    std::string device;
    const device::Parameter* parameter = nullptr;
    OpcuaDataKind kind = OpcuaDataKind::analog;
    bool writable = false;  // the front takes writes and the profile marks the word writable
    void* owner = nullptr;  // the front's state (OpcuaServer::State), which answers its writes
    std::string node_id;    // the string part: "oven.set_point"
    std::optional<std::string> eu_range_id;  // analog only: its EURange and EngineeringUnits properties
    std::optional<std::string> units_id;
    // What a Read answers: none before the first poll (Bad_WaitingForInitialData), then the last
    // value read, kept through stale and silent polls with their status code.
    UA_Variant value{};
    UA_StatusCode status = UA_STATUSCODE_BADWAITINGFORINITIALDATA;
    UA_DateTime source_time = 0;
    device::ValueLimits limits;  // as last shown in EURange
    std::string unit;            // as last shown in EngineeringUnits
};

// A device's Status variable, ns=1;s=DEVICE/status: the gateway's word for it ("ok", "no-reply", ...).
struct OpcuaDeviceStatus {
    std::string device;
    std::string node_id;
    std::string word = "waiting";
    std::string error;
    UA_DateTime source_time = 0;
};

// The variable's DataType: Double, Int16, UInt16, Boolean or String.
const UA_DataType* data_type_of(OpcuaDataKind kind);

// ns=1;s=TEXT.
UA_NodeId string_node(const std::string& text);

// An object under `parent` (Organizes from a folder), browse and display name `name`.
UA_StatusCode add_object(UA_Server* server, const std::string& id, const UA_NodeId& parent, const std::string& name,
                         bool folder);
// The parameter's variable under the device's object, with its data source reading from (and
// writing through) `variable`, which must outlive the server; for an analog one also its
// EURange and EngineeringUnits.
UA_StatusCode add_variable(UA_Server* server, OpcuaVariable& variable, const UA_NodeId& device, const UA_DataSource& source);
UA_StatusCode add_device_status(UA_Server* server, OpcuaDeviceStatus& status, const UA_NodeId& device,
                                const UA_DataSource& source);

// The value and limits of one change (ValueCache), into `variable` and its properties.
struct ShownValue {
    std::optional<device::EngineeringValue> value;
    std::string text;
    std::string unit;
    device::ValueLimits limits;
    std::string status;
    std::chrono::system_clock::time_point sampled;
};
void show(UA_Server* server, OpcuaVariable& variable, const ShownValue& shown);

// The variable's value as the device writer takes it ("150.5", "on", "3"); none for a value of
// another type than the variable's (Bad_TypeMismatch).
std::optional<std::string> write_text(const OpcuaVariable& variable, const UA_Variant& value);
// The number a write gives, for the range check; none for a label or a switch.
std::optional<double> write_number(const UA_Variant& value);

UA_DateTime ua_time(std::chrono::system_clock::time_point time);

}  // namespace loopwire::gateway
