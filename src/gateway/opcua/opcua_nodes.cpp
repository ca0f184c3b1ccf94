#include "gateway/opcua/opcua_nodes.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace loopwire::gateway {
namespace {

// The namespace of UNECE unit codes (OPC UA Part 8, EUInformation).
constexpr const char* unece_namespace = "http://www.opcfoundation.org/UA/units/un/cefact";

// Views of the text, not copies (open62541 copies them into the node): the text must outlive the
// call that adds the node. A literal is taken as it is, never through a temporary std::string,
// whose characters would be gone before the node is added.
UA_LocalizedText text_of(const char* text) { return UA_LOCALIZEDTEXT(const_cast<char*>(""), const_cast<char*>(text)); }
UA_LocalizedText text_of(const std::string& text) { return text_of(text.c_str()); }

UA_QualifiedName name_of(UA_UInt16 ns, const char* name) { return UA_QUALIFIEDNAME(ns, const_cast<char*>(name)); }
UA_QualifiedName name_of(UA_UInt16 ns, const std::string& name) { return name_of(ns, name.c_str()); }

UA_Range range_of(const device::ValueLimits& limits) {
    // A bound not known (set by a parameter not read yet) is NaN: no number is made up for it.
    const double unknown = std::numeric_limits<double>::quiet_NaN();
    return UA_Range{limits.min.value_or(unknown), limits.max.value_or(unknown)};
}

UA_EUInformation units_of(const std::string& unit) {
    UA_EUInformation info;
    UA_EUInformation_init(&info);
    const auto code = unece_unit(unit);
    info.namespaceUri = UA_STRING(const_cast<char*>(code ? unece_namespace : ""));
    info.unitId = code ? code->unit_id : -1;
    info.displayName = text_of(unit);
    info.description = text_of(unit);
    return info;
}

// The property `name` (EURange, EngineeringUnits) of `variable`: the one the type made, else a
// new one of id `id`. Returns its id's string part.
std::string property(UA_Server* server, const UA_NodeId& variable, const std::string& id, const char* name,
                     const UA_DataType* type, void* value) {
    const UA_QualifiedName browse = UA_QUALIFIEDNAME(0, const_cast<char*>(name));
    UA_BrowsePathResult found = UA_Server_browseSimplifiedBrowsePath(server, variable, 1, &browse);
    const bool exists = found.statusCode == UA_STATUSCODE_GOOD && found.targetsSize > 0;
    UA_NodeId node = string_node(id);
    if (exists) {
        UA_NodeId_clear(&node);
        UA_NodeId_copy(&found.targets[0].targetId.nodeId, &node);
    } else {
        UA_VariableAttributes attributes = UA_VariableAttributes_default;
        attributes.displayName = UA_LOCALIZEDTEXT(const_cast<char*>(""), const_cast<char*>(name));
        attributes.dataType = type->typeId;
        attributes.valueRank = UA_VALUERANK_SCALAR;
        UA_Variant_setScalar(&attributes.value, value, type);
        UA_Server_addVariableNode(server, node, variable, UA_NODEID_NUMERIC(0, UA_NS0ID_HASPROPERTY), browse,
                                  UA_NODEID_NUMERIC(0, UA_NS0ID_PROPERTYTYPE), attributes, nullptr, nullptr);
    }
    UA_BrowsePathResult_clear(&found);
    std::string text;
    if (node.identifierType == UA_NODEIDTYPE_STRING) {
        text.assign(reinterpret_cast<const char*>(node.identifier.string.data), node.identifier.string.length);
    } else {
        text = fmt::format("#{}", node.identifier.numeric);  // made by the type: numeric, kept as such below
    }
    UA_NodeId_clear(&node);
    return text;
}

// A property id as property() returns it.
UA_NodeId property_node(const std::string& id) {
    if (!id.empty() && id.front() == '#') return UA_NODEID_NUMERIC(1, static_cast<UA_UInt32>(std::stoul(id.substr(1))));
    return string_node(id);
}

void write_property(UA_Server* server, const std::string& id, void* value, const UA_DataType* type) {
    UA_Variant variant;
    UA_Variant_setScalar(&variant, value, type);
    UA_NodeId node = property_node(id);
    UA_Server_writeValue(server, node, variant);
    UA_NodeId_clear(&node);
}

}  // namespace

const UA_DataType* data_type_of(OpcuaDataKind kind) {
    switch (kind) {
        case OpcuaDataKind::analog: return &UA_TYPES[UA_TYPES_DOUBLE];
        case OpcuaDataKind::int16: return &UA_TYPES[UA_TYPES_INT16];
        case OpcuaDataKind::uint16:
        case OpcuaDataKind::bits: return &UA_TYPES[UA_TYPES_UINT16];
        case OpcuaDataKind::boolean: return &UA_TYPES[UA_TYPES_BOOLEAN];
        case OpcuaDataKind::label: return &UA_TYPES[UA_TYPES_STRING];
    }
    return &UA_TYPES[UA_TYPES_DOUBLE];
}

UA_NodeId string_node(const std::string& text) { return UA_NODEID_STRING_ALLOC(1, text.c_str()); }

UA_DateTime ua_time(std::chrono::system_clock::time_point time) {
    const auto since_epoch = std::chrono::duration_cast<std::chrono::microseconds>(time.time_since_epoch()).count();
    return UA_DATETIME_UNIX_EPOCH + since_epoch * UA_DATETIME_USEC;
}

UA_StatusCode add_object(UA_Server* server, const std::string& id, const UA_NodeId& parent, const std::string& name,
                         bool folder) {
    UA_ObjectAttributes attributes = UA_ObjectAttributes_default;
    attributes.displayName = text_of(name);
    UA_NodeId node = string_node(id);
    const UA_StatusCode added = UA_Server_addObjectNode(
        server, node, parent, UA_NODEID_NUMERIC(0, folder ? UA_NS0ID_ORGANIZES : UA_NS0ID_HASCOMPONENT), name_of(1, name),
        UA_NODEID_NUMERIC(0, folder ? UA_NS0ID_FOLDERTYPE : UA_NS0ID_BASEOBJECTTYPE), attributes, nullptr, nullptr);
    UA_NodeId_clear(&node);
    return added;
}

UA_StatusCode add_variable(UA_Server* server, OpcuaVariable& variable, const UA_NodeId& device, const UA_DataSource& source) {
    const device::Parameter& parameter = *variable.parameter;
    UA_VariableAttributes attributes = UA_VariableAttributes_default;
    attributes.displayName = text_of(parameter.name);
    attributes.description = text_of(parameter.description);
    attributes.dataType = data_type_of(variable.kind)->typeId;
    attributes.valueRank = UA_VALUERANK_SCALAR;
    attributes.accessLevel = UA_ACCESSLEVELMASK_READ | (variable.writable ? UA_ACCESSLEVELMASK_WRITE : 0);
    attributes.userAccessLevel = attributes.accessLevel;
    attributes.minimumSamplingInterval = 0;
    UA_NodeId node = string_node(variable.node_id);
    const bool analog = variable.kind == OpcuaDataKind::analog;
    UA_StatusCode added = UA_Server_addDataSourceVariableNode(
        server, node, device, UA_NODEID_NUMERIC(0, UA_NS0ID_HASCOMPONENT), name_of(1, parameter.name),
        UA_NODEID_NUMERIC(0, analog ? UA_NS0ID_ANALOGITEMTYPE : UA_NS0ID_BASEDATAVARIABLETYPE), attributes, source,
        &variable, nullptr);
    if (added == UA_STATUSCODE_GOOD && analog) {
        UA_Range range = range_of(variable.limits);
        variable.eu_range_id = property(server, node, variable.node_id + "/EURange", "EURange", &UA_TYPES[UA_TYPES_RANGE], &range);
        write_property(server, *variable.eu_range_id, &range, &UA_TYPES[UA_TYPES_RANGE]);
        UA_EUInformation units = units_of(variable.unit);
        variable.units_id = property(server, node, variable.node_id + "/EngineeringUnits", "EngineeringUnits",
                                     &UA_TYPES[UA_TYPES_EUINFORMATION], &units);
        write_property(server, *variable.units_id, &units, &UA_TYPES[UA_TYPES_EUINFORMATION]);
    }
    UA_NodeId_clear(&node);
    return added;
}

UA_StatusCode add_device_status(UA_Server* server, OpcuaDeviceStatus& status, const UA_NodeId& device,
                                const UA_DataSource& source) {
    UA_VariableAttributes attributes = UA_VariableAttributes_default;
    attributes.displayName = text_of("Status");
    attributes.description = text_of("The gateway's word for the device: waiting, ok, partial, no-reply, line-down, stale "
                                     "or wrong-device.");
    attributes.dataType = UA_TYPES[UA_TYPES_STRING].typeId;
    attributes.valueRank = UA_VALUERANK_SCALAR;
    attributes.accessLevel = UA_ACCESSLEVELMASK_READ;
    UA_NodeId node = string_node(status.node_id);
    const UA_StatusCode added = UA_Server_addDataSourceVariableNode(
        server, node, device, UA_NODEID_NUMERIC(0, UA_NS0ID_HASCOMPONENT), name_of(1, "Status"),
        UA_NODEID_NUMERIC(0, UA_NS0ID_BASEDATAVARIABLETYPE), attributes, source, &status, nullptr);
    UA_NodeId_clear(&node);
    return added;
}

void show(UA_Server* server, OpcuaVariable& variable, const ShownValue& shown) {
    variable.status = value_status_code(shown.status);
    variable.source_time = ua_time(shown.sampled);
    if (shown.value) {
        UA_Variant_clear(&variable.value);
        const auto* number = std::get_if<double>(&shown.value->value);
        switch (variable.kind) {
            case OpcuaDataKind::analog:
                if (number) {
                    UA_Double value = *number;
                    UA_Variant_setScalarCopy(&variable.value, &value, &UA_TYPES[UA_TYPES_DOUBLE]);
                }
                break;
            case OpcuaDataKind::int16: {
                UA_Int16 value = static_cast<UA_Int16>(static_cast<std::int16_t>(shown.value->raw));
                UA_Variant_setScalarCopy(&variable.value, &value, &UA_TYPES[UA_TYPES_INT16]);
                break;
            }
            case OpcuaDataKind::uint16:
            case OpcuaDataKind::bits: {
                UA_UInt16 value = shown.value->raw;
                UA_Variant_setScalarCopy(&variable.value, &value, &UA_TYPES[UA_TYPES_UINT16]);
                break;
            }
            case OpcuaDataKind::boolean: {
                UA_Boolean value = shown.value->raw != 0;
                UA_Variant_setScalarCopy(&variable.value, &value, &UA_TYPES[UA_TYPES_BOOLEAN]);
                break;
            }
            case OpcuaDataKind::label: {
                UA_String value = UA_STRING(const_cast<char*>(shown.text.c_str()));
                UA_Variant_setScalarCopy(&variable.value, &value, &UA_TYPES[UA_TYPES_STRING]);
                break;
            }
        }
    }
    if (variable.kind != OpcuaDataKind::analog) return;
    // The limits and unit follow the device's configuration words (a TC10's unit, decimal point,
    // SP.LL/SP.HL): the properties change with them.
    if (shown.status != "stale" && !(shown.limits == variable.limits) && variable.eu_range_id) {
        variable.limits = shown.limits;
        UA_Range range = range_of(variable.limits);
        write_property(server, *variable.eu_range_id, &range, &UA_TYPES[UA_TYPES_RANGE]);
    }
    if (!shown.unit.empty() && shown.unit != variable.unit && variable.units_id) {
        variable.unit = shown.unit;
        UA_EUInformation units = units_of(variable.unit);
        write_property(server, *variable.units_id, &units, &UA_TYPES[UA_TYPES_EUINFORMATION]);
    }
}

std::optional<double> write_number(const UA_Variant& value) {
    if (!UA_Variant_isScalar(&value) || !value.data) return std::nullopt;
    if (value.type == &UA_TYPES[UA_TYPES_DOUBLE]) return *static_cast<const UA_Double*>(value.data);
    if (value.type == &UA_TYPES[UA_TYPES_INT16]) return *static_cast<const UA_Int16*>(value.data);
    if (value.type == &UA_TYPES[UA_TYPES_UINT16]) return *static_cast<const UA_UInt16*>(value.data);
    return std::nullopt;
}

std::optional<std::string> write_text(const OpcuaVariable& variable, const UA_Variant& value) {
    if (!UA_Variant_isScalar(&value) || !value.data || value.type != data_type_of(variable.kind)) return std::nullopt;
    switch (variable.kind) {
        case OpcuaDataKind::analog: {
            const double number = *static_cast<const UA_Double*>(value.data);
            if (!std::isfinite(number)) return std::nullopt;
            return fmt::format("{}", number);  // the shortest text that reads back as this double
        }
        case OpcuaDataKind::int16: return fmt::format("{}", *static_cast<const UA_Int16*>(value.data));
        case OpcuaDataKind::uint16:
        case OpcuaDataKind::bits: return fmt::format("{}", *static_cast<const UA_UInt16*>(value.data));
        case OpcuaDataKind::boolean: return *static_cast<const UA_Boolean*>(value.data) ? "1" : "0";
        case OpcuaDataKind::label: {
            const auto* text = static_cast<const UA_String*>(value.data);
            return std::string(reinterpret_cast<const char*>(text->data), text->length);
        }
    }
    return std::nullopt;
}

}  // namespace loopwire::gateway
