#pragma once
// Read Device Identification: function 43 (encapsulated interface transport) with MEI type 14
// (Modbus application protocol V1.1b3, 6.21). Sans-I/O: pure functions of PDUs.
//
// Request:  2Bh 0Eh read-code object-id
// Reply:    2Bh 0Eh read-code conformity more-follows next-object-id count {id length value}...
// A device without it answers exception 01h (illegal function), which is not this codec's to
// decode: the caller sees ABh and the code.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "common/bytes.hpp"
#include "common/result.hpp"

namespace loopwire::codec {

inline constexpr std::uint8_t encapsulated_interface_function = 43;
inline constexpr std::uint8_t read_device_identification_mei = 14;

// Which objects a request asks for: the basic three (VendorName, ProductCode,
// MajorMinorRevision), the regular ones (up to 7Fh), the extended ones, or one object.
enum class IdentificationCategory : std::uint8_t { basic = 1, regular = 2, extended = 3, one_object = 4 };

struct DeviceIdentificationRequest {
    IdentificationCategory category = IdentificationCategory::basic;
    std::uint8_t first_object = 0;  // where a stream of objects starts (the reply's next id)

    bool operator==(const DeviceIdentificationRequest&) const = default;
};

struct IdentificationObject {
    std::uint8_t id = 0;
    std::string value;  // the bytes as sent: ASCII by the standard, not checked

    bool operator==(const IdentificationObject&) const = default;
};

struct DeviceIdentification {
    IdentificationCategory category = IdentificationCategory::basic;
    std::uint8_t conformity = 0;  // 01h basic .. 03h extended, +80h where single objects are served
    bool more_follows = false;    // the objects did not fit one reply: ask again from next_object
    std::uint8_t next_object = 0;
    std::vector<IdentificationObject> objects;

    bool operator==(const DeviceIdentification&) const = default;
};

Bytes encode_device_identification_request(const DeviceIdentificationRequest& request);
Result<DeviceIdentificationRequest> decode_device_identification_request(ByteView pdu);
// Usage error when the objects do not fit one PDU (253 bytes) or one is longer than 255 bytes.
Result<Bytes> encode_device_identification_reply(const DeviceIdentification& reply);
// Validates everything a receiver can check: function and MEI type, a known category, the
// more-follows byte (00h or FFh), and that the object list fills the PDU exactly. Malformed
// otherwise, with a message saying what was wrong.
Result<DeviceIdentification> decode_device_identification_reply(ByteView pdu);

// "VendorName", "ProductCode", "MajorMinorRevision", "VendorUrl", "ProductName", "ModelName",
// "UserApplicationName" for objects 0..6; "object 0x80" style names for the others.
std::string identification_object_name(std::uint8_t id);

}  // namespace loopwire::codec
