#include "client/dump_document.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include <fmt/format.h>

#include "profile/value_format.hpp"

namespace loopwire::device {

std::vector<const device::Parameter*> dumped_parameters(const device::Profile& profile) {
    std::vector<const device::Parameter*> list;
    for (const auto& p : profile.parameters) {
        if (p.readable) list.push_back(&p);
    }
    return list;
}

namespace {

Result<nlohmann::ordered_json> parameter_entry(const device::ParameterReading& reading, const device::RawValues& known) {
    const auto& p = *reading.parameter;
    const std::string unit = device::unit_of(p, known);  // the unit the configuration read gives
    if (!reading.value) {
        // A word read but not decoded (its decimals word reads 0xFFFF, say): the word is kept,
        // so restore can write back exactly what the device held.
        if (const auto raw = known.find(p.name); raw != known.end()) {
            return nlohmann::ordered_json{{"value", nullptr}, {"text", nullptr}, {"unit", unit},
                                          {"raw", nlohmann::ordered_json::array({raw->second})}, {"status", "undecodable"},
                                          {"error", reading.error}, {"writable", p.writable}};
        }
        return nlohmann::ordered_json{{"value", nullptr}, {"text", nullptr}, {"unit", unit}, {"raw", nlohmann::ordered_json::array()},
                                      {"status", "unread"}, {"error", reading.error}, {"writable", p.writable}};
    }
    auto text = device::format_value(p, *reading.value, known);
    if (!text) {
        return nlohmann::ordered_json{{"value", nullptr}, {"text", nullptr}, {"unit", unit},
                                      {"raw", nlohmann::ordered_json::array({reading.value->raw})}, {"status", "undecodable"},
                                      {"error", text.error().message}, {"writable", p.writable}};
    }
    auto entry = value_json(p, *reading.value);
    return nlohmann::ordered_json{{"value", entry["value"]}, {"text", *text}, {"unit", unit},
                                  {"raw", nlohmann::ordered_json::array({reading.value->raw})},
                                  {"status", reading.value->status}, {"writable", p.writable}};
}

nlohmann::ordered_json identification_of(const device::Profile& profile, const device::RawValues& raw) {
    nlohmann::ordered_json identification = nlohmann::ordered_json::object();
    for (const auto& name : profile.identification_report) {
        if (auto word = raw.find(name); word != raw.end()) identification[name] = word->second;
    }
    return identification;
}

}  // namespace

Result<nlohmann::ordered_json> dump_document(const device::DeviceAddress& device, const DumpHeader& header,
                                             const device::ReadReport& report) {
    const auto& profile = *device.profile;
    nlohmann::ordered_json parameters = nlohmann::ordered_json::object();
    for (const auto& reading : report.readings) {
        auto entry = parameter_entry(reading, report.raw);
        if (!entry) return entry.error();
        parameters[reading.parameter->name] = std::move(*entry);
    }
    nlohmann::ordered_json document{{"format", "loopwire-dump"}, {"version", 1}, {"profile", profile.id}, {"unit", device.unit},
                                    {"link", header.link}, {"time", header.time}};
    if (!header.numbering.empty()) document["numbering"] = header.numbering;
    document["identification"] = identification_of(profile, report.raw);
    document["parameters"] = std::move(parameters);
    return document;
}

}  // namespace loopwire::device
