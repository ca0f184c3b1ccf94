#include "gateway/opcua/opcua_status.hpp"

#include <array>
#include <utility>

#include <open62541/statuscodes.h>

namespace loopwire::gateway {

OpcuaDataKind opcua_data_kind(const device::Parameter& parameter) {
    switch (parameter.type) {
        case device::ValueType::boolean: return OpcuaDataKind::boolean;
        case device::ValueType::enumeration: return OpcuaDataKind::label;
        case device::ValueType::bitfield: return OpcuaDataKind::bits;
        case device::ValueType::int16:
        case device::ValueType::uint16: break;
    }
    const bool decimals = std::holds_alternative<std::string>(parameter.decimals) || std::get<int>(parameter.decimals) != 0;
    const bool unit = !parameter.unit.empty() || !parameter.unit_from.empty();
    if (decimals || unit) return OpcuaDataKind::analog;
    return parameter.type == device::ValueType::int16 ? OpcuaDataKind::int16 : OpcuaDataKind::uint16;
}

std::uint32_t value_status_code(std::string_view status) {
    if (status == "ok" || status == "unknown-label") return UA_STATUSCODE_GOOD;
    if (status == "stale") return UA_STATUSCODE_UNCERTAINLASTUSABLEVALUE;
    if (status == "no-reply") return UA_STATUSCODE_BADNOCOMMUNICATION;
    if (status == "line-down") return UA_STATUSCODE_BADNOTCONNECTED;
    if (status == "error") return UA_STATUSCODE_BADDEVICEFAILURE;
    return UA_STATUSCODE_BADSENSORFAILURE;  // the profile's special states: under-range, not-available, ...
}

std::uint32_t device_status_code(device::DeviceStatus status) {
    switch (status) {
        case device::DeviceStatus::waiting: return UA_STATUSCODE_BADWAITINGFORINITIALDATA;
        case device::DeviceStatus::ok:
        case device::DeviceStatus::partial: return UA_STATUSCODE_GOOD;
        case device::DeviceStatus::no_reply: return UA_STATUSCODE_BADNOCOMMUNICATION;
        case device::DeviceStatus::line_down: return UA_STATUSCODE_BADNOTCONNECTED;
        case device::DeviceStatus::stale: return UA_STATUSCODE_UNCERTAINLASTUSABLEVALUE;
        case device::DeviceStatus::wrong_device: return UA_STATUSCODE_BADCONFIGURATIONERROR;
    }
    return UA_STATUSCODE_BADINTERNALERROR;  // not reached: every status is handled above
}

std::uint32_t write_error_code(const Error& error, bool unsent) {
    if (unsent) return UA_STATUSCODE_BADNOCOMMUNICATION;
    switch (error.kind) {
        case ErrorKind::timeout: return UA_STATUSCODE_BADTIMEOUT;
        case ErrorKind::link:
        case ErrorKind::mismatch:
        case ErrorKind::malformed: return UA_STATUSCODE_BADNOCOMMUNICATION;
        case ErrorKind::usage: return UA_STATUSCODE_BADOUTOFRANGE;
        case ErrorKind::exception:
            if (error.code == 0x02) return UA_STATUSCODE_BADNOTWRITABLE;
            if (error.code == 0x03) return UA_STATUSCODE_BADOUTOFRANGE;
            return UA_STATUSCODE_BADDEVICEFAILURE;
    }
    return UA_STATUSCODE_BADINTERNALERROR;  // not reached
}

std::optional<UneceUnit> unece_unit(std::string_view unit) {
    // The units the profiles use, and the common ones a profile file may bring.
    static constexpr std::array<std::pair<std::string_view, std::string_view>, 17> codes{{
        {"°C", "CEL"}, {"°F", "FAH"}, {"K", "KEL"}, {"%", "P1"}, {"s", "SEC"}, {"min", "MIN"}, {"h", "HUR"},
        {"d", "DAY"}, {"A", "AMP"}, {"mA", "4K"}, {"V", "VLT"}, {"mV", "2Z"}, {"kΩ", "B49"}, {"Ω", "OHM"},
        {"Hz", "HTZ"}, {"bar", "BAR"}, {"W", "WTT"},
    }};
    for (const auto& [name, code] : codes) {
        if (name != unit) continue;
        std::int32_t id = 0;
        for (char c : code) id = (id << 8) | static_cast<unsigned char>(c);
        return UneceUnit{std::string(code), id};
    }
    return std::nullopt;
}

}  // namespace loopwire::gateway
