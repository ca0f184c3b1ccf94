#include "device/device_client.hpp"

#include <algorithm>
#include <set>

#include <fmt/format.h>

namespace loopwire::device {
namespace {

codec::FunctionCode read_function(Table table) {
    switch (table) {
        case Table::holding: return codec::FunctionCode::read_holding_registers;
        case Table::input: return codec::FunctionCode::read_input_registers;
        case Table::coils: return codec::FunctionCode::read_coils;
        case Table::discrete: return codec::FunctionCode::read_discrete_inputs;
    }
    return codec::FunctionCode::read_holding_registers;
}

bool is_bit_table(Table table) { return table == Table::coils || table == Table::discrete; }

codec::Request write_request(const WriteBlock& block) {
    const bool bits = is_bit_table(block.table);
    if (block.single) {
        return bits ? codec::write_single_coil(block.wire_address, block.values.at(0) != 0)
                    : codec::write_single_register(block.wire_address, block.values.at(0));
    }
    return bits ? codec::write_multiple_coils(block.wire_address, block.values)
                : codec::write_multiple_registers(block.wire_address, block.values);
}

// The parameters to read so that every wanted one can be decoded (decimals from other words).
std::vector<const Parameter*> with_dependencies(const Profile& profile, const std::vector<const Parameter*>& wanted) {
    std::vector<const Parameter*> all = wanted;
    std::set<const Parameter*> seen(wanted.begin(), wanted.end());
    for (const Parameter* parameter : wanted) {
        if (const auto* source = std::get_if<std::string>(&parameter->decimals)) {
            const Parameter* dependency = profile.find(*source);
            if (dependency && dependency->readable && seen.insert(dependency).second) all.push_back(dependency);
        }
    }
    return all;
}

}  // namespace

Result<DeviceAddress> parse_device_address(const std::string& text, const std::string& numbering) {
    const auto at = text.find('@');
    const std::string id = text.substr(0, at);
    auto profile = builtin_profile(id);
    if (!profile) return profile.error();
    DeviceAddress device{*profile, 1, 0};
    if (at != std::string::npos) {
        const std::string unit = text.substr(at + 1);
        int value = -1;
        try {
            std::size_t used = 0;
            value = std::stoi(unit, &used);
            if (used != unit.size()) value = -1;
        } catch (...) {
            value = -1;
        }
        if (value < 1 || value > 247) {
            return make_error(ErrorKind::usage, fmt::format("'{}': the unit after '@' must be 1..247 (e.g. {}@3)", text, id));
        }
        device.unit = static_cast<std::uint8_t>(value);
    }
    if (!numbering.empty()) {
        const auto& choices = device.profile->numberings;
        auto it = std::find_if(choices.begin(), choices.end(), [&](const auto& n) { return n.name == numbering; });
        if (it == choices.end()) {
            std::vector<std::string> names;
            for (const auto& n : choices) names.push_back(n.name);
            return make_error(ErrorKind::usage,
                              fmt::format("{} has no numbering '{}' ({})", id, numbering,
                                          names.empty() ? "it has only its own" : "choices: " + fmt::format("{}", fmt::join(names, ", "))));
        }
        device.address_offset = it->offset;
    }
    return device;
}

DeviceClient::DeviceClient(session::Master& master, DeviceAddress device) : master_(master), device_(std::move(device)) {}

Error DeviceClient::explain(Error error) const {
    if (error.kind != ErrorKind::exception) return error;
    auto it = device_.profile->exception_names.find(static_cast<std::uint8_t>(error.code));
    if (it != device_.profile->exception_names.end()) {
        error.message += fmt::format(" — {} manual: {}", device_.profile->id, it->second);
    }
    return error;
}

Result<codec::Reply> DeviceClient::execute_read(const ReadBlock& block) {
    return master_.execute(device_.unit, codec::read_request(read_function(block.table), block.wire_address, block.count));
}

ReadReport DeviceClient::read(const std::vector<const Parameter*>& parameters) {
    ReadReport report;
    std::map<const Parameter*, std::string> failures;
    for (const ReadBlock& block : plan_reads(*device_.profile, with_dependencies(*device_.profile, parameters), device_.address_offset)) {
        ++report.requests;
        auto reply = execute_read(block);
        if (!reply) {
            const Error error = explain(reply.error());
            if (!report.first_error) report.first_error = error;
            for (const Parameter* p : block.parameters) failures[p] = error.message;
            continue;
        }
        for (const Parameter* p : block.parameters) {
            const int wire = p->address + device_.address_offset;
            report.raw[p->name] = reply->values.at(static_cast<std::size_t>(wire - block.wire_address));
        }
    }
    for (const Parameter* p : parameters) {
        ParameterReading reading{p, std::nullopt, {}};
        if (auto failed = failures.find(p); failed != failures.end()) {
            reading.error = failed->second;
        } else if (auto raw = report.raw.find(p->name); raw != report.raw.end()) {
            auto value = decode_value(*p, raw->second, report.raw);
            if (value) reading.value = std::move(*value);
            else reading.error = value.error().message;
        } else {
            reading.error = "not read";
        }
        report.readings.push_back(std::move(reading));
    }
    return report;
}

Result<WriteReport> DeviceClient::write(const std::vector<std::pair<const Parameter*, std::string>>& assignments) {
    // What the new values are checked against: decimals and range bounds held by other words.
    std::vector<const Parameter*> needed;
    for (const auto& [parameter, text] : assignments) {
        for (const auto& name : dependencies_of(*parameter)) {
            if (const Parameter* dependency = device_.profile->find(name); dependency && dependency->readable) needed.push_back(dependency);
        }
    }
    RawValues known;
    if (!needed.empty()) {
        auto current = read(needed);
        if (current.first_error) return *current.first_error;
        known = std::move(current.raw);
    }
    std::vector<PlannedWrite> planned;
    for (const auto& [parameter, text] : assignments) {
        auto raw = encode_value(*parameter, text, known);
        if (!raw) return raw.error();
        planned.push_back({parameter, *raw});
        known[parameter->name] = *raw;  // later bounds see the new value (TC10 SPLL before SP)
    }
    WriteReport report;
    for (const WriteBlock& block : plan_writes(*device_.profile, planned, device_.address_offset)) {
        ++report.requests;
        auto reply = master_.execute(device_.unit, write_request(block));
        if (!reply) {
            Error error = explain(reply.error());
            std::vector<std::string> done;
            for (const auto& [p, raw] : report.written) done.push_back(p->name);
            error.message += fmt::format("; written before the failure: {}", done.empty() ? "nothing" : fmt::format("{}", fmt::join(done, ", ")));
            return error;
        }
        for (std::size_t i = 0; i < block.parameters.size(); ++i) report.written.emplace_back(block.parameters[i], block.values[i]);
    }
    return report;
}

}  // namespace loopwire::device
