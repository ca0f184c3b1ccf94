// The OPC UA front's words for values, devices and writes (gateway/opcua/opcua_status.hpp).
#include "gateway/opcua/opcua_status.hpp"

#include <gtest/gtest.h>
#include <open62541/statuscodes.h>

namespace loopwire::gateway {
namespace {

TEST(OpcuaStatus, ValueStatusesMapOnce) {
    EXPECT_EQ(value_status_code("ok"), UA_STATUSCODE_GOOD);
    EXPECT_EQ(value_status_code("unknown-label"), UA_STATUSCODE_GOOD);
    EXPECT_EQ(value_status_code("stale"), UA_STATUSCODE_UNCERTAINLASTUSABLEVALUE);
    EXPECT_EQ(value_status_code("no-reply"), UA_STATUSCODE_BADNOCOMMUNICATION);
    EXPECT_EQ(value_status_code("line-down"), UA_STATUSCODE_BADNOTCONNECTED);
    EXPECT_EQ(value_status_code("error"), UA_STATUSCODE_BADDEVICEFAILURE);
    EXPECT_EQ(value_status_code("under-range"), UA_STATUSCODE_BADSENSORFAILURE);
}

TEST(OpcuaStatus, DeviceWaitingIsWaitingForInitialData) {
    EXPECT_EQ(device_status_code(device::DeviceStatus::waiting), UA_STATUSCODE_BADWAITINGFORINITIALDATA);
    EXPECT_EQ(device_status_code(device::DeviceStatus::partial), UA_STATUSCODE_GOOD);
    EXPECT_EQ(device_status_code(device::DeviceStatus::stale), UA_STATUSCODE_UNCERTAINLASTUSABLEVALUE);
    EXPECT_EQ(device_status_code(device::DeviceStatus::line_down), UA_STATUSCODE_BADNOTCONNECTED);
}

TEST(OpcuaStatus, WriteErrorsSayWhatTheDeviceDid) {
    EXPECT_EQ(write_error_code(make_error(ErrorKind::timeout, "silent"), true), UA_STATUSCODE_BADNOCOMMUNICATION);
    EXPECT_EQ(write_error_code(make_error(ErrorKind::timeout, "no reply"), false), UA_STATUSCODE_BADTIMEOUT);
    EXPECT_EQ(write_error_code(make_error(ErrorKind::link, "down"), false), UA_STATUSCODE_BADNOCOMMUNICATION);
    EXPECT_EQ(write_error_code(make_error(ErrorKind::usage, "outside -1999..9999"), false), UA_STATUSCODE_BADOUTOFRANGE);
    EXPECT_EQ(write_error_code(make_error(ErrorKind::exception, "illegal address", 2), false), UA_STATUSCODE_BADNOTWRITABLE);
    EXPECT_EQ(write_error_code(make_error(ErrorKind::exception, "illegal value", 3), false), UA_STATUSCODE_BADOUTOFRANGE);
}

TEST(OpcuaStatus, UnitsCarryUneceCodes) {
    // OPC UA Part 8: the code's characters, 8 bits each ("CEL" = 0x43454C).
    EXPECT_EQ(unece_unit("°C")->unit_id, 0x43454C);
    EXPECT_EQ(unece_unit("°F")->code, "FAH");
    EXPECT_EQ(unece_unit("%")->unit_id, 0x5031);
    EXPECT_EQ(unece_unit("s")->code, "SEC");
    EXPECT_FALSE(unece_unit("units/min"));
}

TEST(OpcuaStatus, ScaledNumbersAreAnalogWholeWordsAreNot) {
    device::Parameter temperature;
    temperature.type = device::ValueType::int16;
    temperature.unit = "°C";
    EXPECT_EQ(opcua_data_kind(temperature), OpcuaDataKind::analog);
    device::Parameter tenths;
    tenths.decimals = 1;
    EXPECT_EQ(opcua_data_kind(tenths), OpcuaDataKind::analog);
    device::Parameter count;
    count.type = device::ValueType::uint16;
    EXPECT_EQ(opcua_data_kind(count), OpcuaDataKind::uint16);
    count.type = device::ValueType::int16;
    EXPECT_EQ(opcua_data_kind(count), OpcuaDataKind::int16);
    device::Parameter mode;
    mode.type = device::ValueType::enumeration;
    EXPECT_EQ(opcua_data_kind(mode), OpcuaDataKind::label);
}

}  // namespace
}  // namespace loopwire::gateway
