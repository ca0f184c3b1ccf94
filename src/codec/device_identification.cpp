#include "codec/device_identification.hpp"

#include <array>

#include <fmt/format.h>

namespace loopwire::codec {
namespace {

constexpr std::size_t max_pdu = 253;
constexpr std::size_t reply_header_size = 7;  // function, MEI, category, conformity, more, next, count
constexpr std::uint8_t more_follows_yes = 0xFF;

Error malformed(const std::string& what) {
    return make_error(ErrorKind::malformed, "read device identification: " + what);
}

bool is_category(std::uint8_t code) { return code >= 1 && code <= 4; }

Result<void> check_header(ByteView pdu, std::size_t least) {
    if (pdu.size() < least) return malformed(fmt::format("{} bytes, at least {} expected", pdu.size(), least));
    if (pdu[0] != encapsulated_interface_function) return malformed(fmt::format("function {}, not 43", pdu[0]));
    if (pdu[1] != read_device_identification_mei) return malformed(fmt::format("MEI type {}, not 14", pdu[1]));
    if (!is_category(pdu[2])) return malformed(fmt::format("read device id code {} is not 1 to 4", pdu[2]));
    return {};
}

}  // namespace

Bytes encode_device_identification_request(const DeviceIdentificationRequest& request) {
    return Bytes{encapsulated_interface_function, read_device_identification_mei,
                 static_cast<std::uint8_t>(request.category), request.first_object};
}

Result<DeviceIdentificationRequest> decode_device_identification_request(ByteView pdu) {
    if (auto ok = check_header(pdu, 4); !ok) return ok.error();
    if (pdu.size() != 4) return malformed(fmt::format("a request is 4 bytes, not {}", pdu.size()));
    return DeviceIdentificationRequest{static_cast<IdentificationCategory>(pdu[2]), pdu[3]};
}

Result<Bytes> encode_device_identification_reply(const DeviceIdentification& reply) {
    if (reply.objects.size() > 255) return make_error(ErrorKind::usage, "read device identification: more than 255 objects");
    Bytes pdu{encapsulated_interface_function,
              read_device_identification_mei,
              static_cast<std::uint8_t>(reply.category),
              reply.conformity,
              static_cast<std::uint8_t>(reply.more_follows ? more_follows_yes : 0),
              reply.next_object,
              static_cast<std::uint8_t>(reply.objects.size())};
    for (const auto& object : reply.objects) {
        if (object.value.size() > 255) {
            return make_error(ErrorKind::usage, fmt::format("read device identification: {} is longer than 255 bytes",
                                                            identification_object_name(object.id)));
        }
        pdu.push_back(object.id);
        pdu.push_back(static_cast<std::uint8_t>(object.value.size()));
        pdu.insert(pdu.end(), object.value.begin(), object.value.end());
    }
    if (pdu.size() > max_pdu) {
        return make_error(ErrorKind::usage, fmt::format("read device identification: the objects take {} bytes, more "
                                                        "than a PDU's {}: send them in parts (more follows)",
                                                        pdu.size(), max_pdu));
    }
    return pdu;
}

Result<DeviceIdentification> decode_device_identification_reply(ByteView pdu) {
    if (auto ok = check_header(pdu, reply_header_size); !ok) return ok.error();
    if (pdu.size() > max_pdu) return malformed(fmt::format("{} bytes, more than a PDU's {}", pdu.size(), max_pdu));
    DeviceIdentification reply;
    reply.category = static_cast<IdentificationCategory>(pdu[2]);
    reply.conformity = pdu[3];
    if (pdu[4] != 0 && pdu[4] != more_follows_yes) return malformed(fmt::format("more-follows byte {:02X}h is not 00h or FFh", pdu[4]));
    reply.more_follows = pdu[4] == more_follows_yes;
    reply.next_object = pdu[5];
    const std::size_t count = pdu[6];
    std::size_t at = reply_header_size;
    for (std::size_t i = 0; i < count; ++i) {
        if (at + 2 > pdu.size()) return malformed(fmt::format("the reply ends inside object {} of {}", i + 1, count));
        const std::uint8_t id = pdu[at];
        const std::size_t length = pdu[at + 1];
        at += 2;
        if (at + length > pdu.size()) {
            return malformed(fmt::format("{} says {} bytes, {} are left", identification_object_name(id), length, pdu.size() - at));
        }
        reply.objects.push_back({id, std::string(pdu.begin() + static_cast<std::ptrdiff_t>(at),
                                                 pdu.begin() + static_cast<std::ptrdiff_t>(at + length))});
        at += length;
    }
    if (at != pdu.size()) return malformed(fmt::format("{} bytes after the {} objects it lists", pdu.size() - at, count));
    return reply;
}

std::string identification_object_name(std::uint8_t id) {
    static constexpr std::array<const char*, 7> names{"VendorName",  "ProductCode", "MajorMinorRevision", "VendorUrl",
                                                      "ProductName", "ModelName",   "UserApplicationName"};
    if (id < names.size()) return names[id];
    return fmt::format("object 0x{:02X}", id);
}

}  // namespace loopwire::codec
