#include "client/device_identity.hpp"

#include <algorithm>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

using codec::IdentificationCategory;
using codec::IdentificationObject;

constexpr std::uint8_t exception_flag = 0x80;
// A reply stream of more than this many parts is a unit that never says it is done.
constexpr int most_parts = 16;

// Exceptions that mean "not here": no such function, or no such category or object.
bool means_none(std::uint8_t code) { return code == 1 || code == 2 || code == 3; }

struct Stream {
    std::uint8_t conformity = 0;
    std::vector<IdentificationObject> objects;
};

// One category, asked again from the next object while the unit says more follows.
Result<std::optional<Stream>> read_category(session::Master& master, std::uint8_t unit, IdentificationCategory category) {
    Stream stream;
    std::uint8_t next = 0;
    for (int part = 0; part < most_parts; ++part) {
        const Bytes request = codec::encode_device_identification_request({category, next});
        auto pdu = master.forward(unit, request);
        if (!pdu) return pdu.error();
        if (pdu->size() == 2 && (*pdu)[0] == (codec::encapsulated_interface_function | exception_flag)) {
            if (means_none((*pdu)[1])) return std::optional<Stream>{};
            return make_error(ErrorKind::exception, fmt::format("unit {} refused Read Device Identification with exception {}",
                                                                unit, (*pdu)[1]));
        }
        auto reply = codec::decode_device_identification_reply(*pdu);
        if (!reply) return reply.error();
        stream.conformity = reply->conformity;
        stream.objects.insert(stream.objects.end(), reply->objects.begin(), reply->objects.end());
        if (!reply->more_follows) return std::optional<Stream>{std::move(stream)};
        next = reply->next_object;
    }
    return make_error(ErrorKind::malformed, fmt::format("unit {} said more objects follow {} times over", unit, most_parts));
}

}  // namespace

Result<std::optional<std::vector<IdentificationObject>>> read_device_identity(session::Master& master, std::uint8_t unit) {
    using Objects = std::optional<std::vector<IdentificationObject>>;
    auto basic = read_category(master, unit, IdentificationCategory::basic);
    if (!basic) return basic.error();
    if (!*basic) return Objects{};
    std::vector<IdentificationObject> objects = std::move(basic->value().objects);
    // Conformity 02h (or 82h) and above: the regular objects too. Units differ on whether a
    // regular stream repeats the basic objects, so each id is kept once; a unit that fails the
    // regular request after answering the basic one still has its basic objects.
    if ((basic->value().conformity & 0x7F) >= 2) {
        auto regular = read_category(master, unit, IdentificationCategory::regular);
        if (regular && *regular) {
            for (auto& object : regular->value().objects) {
                const bool known = std::any_of(objects.begin(), objects.end(),
                                               [&](const IdentificationObject& each) { return each.id == object.id; });
                if (!known) objects.push_back(std::move(object));
            }
        }
    }
    return Objects{std::move(objects)};
}

nlohmann::ordered_json identity_json(const std::vector<IdentificationObject>& objects) {
    nlohmann::ordered_json out = nlohmann::ordered_json::object();
    // The standard says ASCII; anything else is shown as '?' rather than carried into JSON,
    // which must be UTF-8.
    for (const auto& object : objects) {
        std::string shown = object.value;
        for (char& c : shown) {
            if (c < 0x20 || c > 0x7E) c = '?';
        }
        out[codec::identification_object_name(object.id)] = shown;
    }
    return out;
}

}  // namespace loopwire::device
