#include "client/device_client.hpp"

#include <algorithm>
#include <deque>
#include <memory>
#include <set>

#include <fmt/format.h>

#include "client/identity_check.hpp"
#include "codec/pdu.hpp"
#include "common/text_parsing.hpp"

namespace loopwire::device {
namespace {

using codec::is_bit_table;
using codec::read_function;

codec::Request write_request(const WriteBlock& block) {
    const bool bits = is_bit_table(block.table);
    if (block.single) {
        return bits ? codec::write_single_coil(block.wire_address, block.values.at(0) != 0)
                    : codec::write_single_register(block.wire_address, block.values.at(0));
    }
    return bits ? codec::write_multiple_coils(block.wire_address, block.values)
                : codec::write_multiple_registers(block.wire_address, block.values);
}

// The parameters to read so that every wanted one can be decoded and shown (decimals and units
// from other words).
std::vector<const Parameter*> with_dependencies(const Profile& profile, const std::vector<const Parameter*>& wanted) {
    std::vector<const Parameter*> all = wanted;
    std::set<const Parameter*> seen(wanted.begin(), wanted.end());
    const auto add = [&](const std::string& name) {
        const Parameter* dependency = profile.find(name);
        if (dependency && dependency->readable && seen.insert(dependency).second) all.push_back(dependency);
    };
    for (const Parameter* parameter : wanted) {
        if (const auto* source = std::get_if<std::string>(&parameter->decimals)) add(*source);
        for (const UnitRule& rule : parameter->unit_from) add(rule.parameter);  // the unit read with the value
    }
    return all;
}

}  // namespace

Result<DeviceName> split_device_address(const std::string& text) {
    const auto at = text.find('@');
    DeviceName name{text.substr(0, at), 1};
    if (at == std::string::npos) return name;
    const auto unit = parse_decimal_digits(std::string_view(text).substr(at + 1));
    if (!unit || *unit < 1 || *unit > 255) {
        return make_error(ErrorKind::usage, fmt::format("'{}': the unit after '@' must be 1..255 (e.g. {}@3)", text, name.id));
    }
    name.unit = static_cast<std::uint8_t>(*unit);  // 1..255, checked above; the profile's unit_ids next
    return name;
}

namespace {

Result<DeviceAddress> device_address(const Result<std::shared_ptr<const Profile>>& profile, const DeviceName& name,
                                     const std::string& numbering) {
    if (!profile) return profile.error();
    // Each manual's own address range, not Modbus's 1..247 (AC20 Introduction and ramp/soak
    // §4.2: 1-255; TC10 #131 Add: up to 254).
    if (unsigned{name.unit} < (*profile)->first_unit || unsigned{name.unit} > (*profile)->last_unit) {
        // "an ac20", "a tc10": the id as it is spoken, letter by letter or as a word.
        const bool vowel = !name.id.empty() && std::string_view("aeiouAEIOU").find(name.id.front()) != std::string_view::npos;
        return make_error(ErrorKind::usage, fmt::format("{}@{}: {} {} is set to a unit {}..{}", name.id, name.unit,
                                                        vowel ? "an" : "a", name.id, (*profile)->first_unit, (*profile)->last_unit));
    }
    DeviceAddress device{*profile, name.unit, 0};
    if (!numbering.empty()) {
        const auto& choices = device.profile->numberings;
        auto it = std::find_if(choices.begin(), choices.end(), [&](const auto& n) { return n.name == numbering; });
        if (it == choices.end()) {
            std::vector<std::string> names;
            for (const auto& n : choices) names.push_back(n.name);
            return make_error(ErrorKind::usage,
                              fmt::format("{} has no numbering '{}' ({})", name.id, numbering,
                                          names.empty() ? "it has only its own" : "choices: " + fmt::format("{}", fmt::join(names, ", "))));
        }
        device.address_offset = it->offset;
    }
    return device;
}

}  // namespace

Result<DeviceAddress> parse_device_address(const ProfileRegistry& profiles, const std::string& text, const std::string& numbering) {
    auto name = split_device_address(text);
    if (!name) return name.error();
    return device_address(profiles.find(name->id), *name, numbering);
}

Result<DeviceAddress> parse_device_address(const std::string& text, const std::string& numbering) {
    auto name = split_device_address(text);
    if (!name) return name.error();
    return device_address(builtin_profile(name->id), *name, numbering);
}

DeviceClient::DeviceClient(session::Master& master, DeviceAddress device) : master_(master), device_(std::move(device)) {}

Error DeviceClient::explain(Error error) const {
    if (error.kind != ErrorKind::exception) return error;
    auto it = device_.profile->exception_names.find(static_cast<std::uint8_t>(error.code));
    if (it != device_.profile->exception_names.end()) {
        // A device may give a standard code its own meaning (the AC20's 10, "cannot be
        // modified", is the standard's "gateway path unavailable"): its manual's word wins.
        if (const auto standard = codec::exception_name(static_cast<std::uint8_t>(error.code))) {
            const std::string shown = " (" + *standard + ")";
            if (const auto at = error.message.find(shown); at != std::string::npos) error.message.erase(at, shown.size());
        }
        error.message += fmt::format(" — {} manual: {}", device_.profile->id, it->second);
    }
    return error;
}

codec::Request DeviceClient::read_request_of(const ReadBlock& block) const {
    return codec::read_request(read_function(block.table), block.wire_address, block.count);
}

std::vector<ReadBlock> DeviceClient::plan(const std::vector<const Parameter*>& parameters) const {
    return plan_reads(*device_.profile, with_dependencies(*device_.profile, parameters), device_.address_offset);
}

// A device may refuse a whole block for some of its words (an AC20 in a start-up error condition
// answers only its configuration, control and security words): on an exception, each parameter
// is asked for alone, so every word it answers is read.
std::vector<ReadBlock> DeviceClient::split(const ReadBlock& block) const {
    std::vector<ReadBlock> singles;
    for (const Parameter* p : block.parameters) {
        for (ReadBlock& single : plan_reads(*device_.profile, {p}, device_.address_offset)) singles.push_back(std::move(single));
    }
    return singles;
}

bool DeviceClient::file_block(const ReadBlock& block, Result<codec::Reply> reply, ReadReport& report, Failures& failures,
                              bool may_split) const {
    ++report.requests;
    if (!reply) {
        const Error error = explain(reply.error());
        if (may_split && error.kind == ErrorKind::exception) return false;
        if (!report.first_error) report.first_error = error;
        for (const Parameter* p : block.parameters) failures[p] = error.message;
        return true;
    }
    for (const Parameter* p : block.parameters) {
        const int wire = p->address + device_.address_offset;
        report.raw[p->name] = reply->values.at(static_cast<std::size_t>(wire - block.wire_address));
    }
    return true;
}

void DeviceClient::decode_readings(const std::vector<const Parameter*>& parameters, ReadReport& report,
                                   const Failures& failures) const {
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
}

std::optional<DeviceAddress> identify_unit(session::Master& master, int unit) {
    for (const auto& id : builtin_profile_ids()) {
        auto address = parse_device_address(id + "@" + std::to_string(unit));
        if (!address) continue;
        const auto checks = identification_words(*address->profile);
        if (checks.empty()) continue;
        const auto report = DeviceClient(master, *address).read(checks);
        if (judge_identity(*address->profile, report).kind == IdentityVerdict::Kind::holds) return *address;
    }
    return std::nullopt;
}

Result<void> DeviceClient::confirm_identity() {
    const Profile& profile = *device_.profile;
    const std::vector<const Parameter*> words = identification_words(profile);
    if (words.empty()) return {};
    const auto report = read(words);
    const auto verdict = judge_identity(profile, report);
    if (verdict.kind == IdentityVerdict::Kind::wrong) {
        // Named by what answers there when a built-in profile recognises it (an AC20 asked for
        // as a TC10), else the way to find out.
        const auto there = identify_unit(master_, device_.unit);
        const std::string what = there ? fmt::format("It answers as {}@{}", there->profile->id, device_.unit)
                                       : fmt::format("`loopwire scan --link URL --units {}` tells what it is", device_.unit);
        return make_error(ErrorKind::mismatch, fmt::format("the device at unit {0} is not {1}@{0}: {2}. {3}; --no-identify talks to "
                                                           "it as {1} anyway",
                                                           device_.unit, profile.id, verdict.reason, what));
    }
    // Not judged: an exception other than 01h/02h is a device that answers but cannot now, and
    // the read that follows reports it; a timeout or link failure is returned as it is.
    if (verdict.kind == IdentityVerdict::Kind::unknown && report.first_error &&
        report.first_error->kind != ErrorKind::exception) {
        return *report.first_error;
    }
    return {};
}

ReadReport DeviceClient::read(const std::vector<const Parameter*>& parameters) { return read_planned(parameters, plan(parameters)); }

ReadReport DeviceClient::read_with_limits(const std::vector<const Parameter*>& parameters) {
    std::vector<const Parameter*> with_bounds = parameters;
    std::set<const Parameter*> seen(with_bounds.begin(), with_bounds.end());
    for (const Parameter* parameter : parameters) {
        // Decimals and unit words, as read() takes them, and the bounds with their decimals.
        for (const std::string& name : dependencies_of(*parameter)) {
            const Parameter* dependency = device_.profile->find(name);
            if (dependency && dependency->readable && seen.insert(dependency).second) with_bounds.push_back(dependency);
        }
    }
    return read_planned(parameters, plan_reads(*device_.profile, with_bounds, device_.address_offset));
}

ReadReport DeviceClient::read_planned(const std::vector<const Parameter*>& parameters, const std::vector<ReadBlock>& blocks) {
    ReadReport report;
    Failures failures;
    for (const ReadBlock& block : blocks) {
        const bool may_split = block.parameters.size() > 1;
        if (file_block(block, master_.execute(device_.unit, read_request_of(block)), report, failures, may_split)) continue;
        for (const ReadBlock& single : split(block)) {
            file_block(single, master_.execute(device_.unit, read_request_of(single)), report, failures, false);
        }
    }
    decode_readings(parameters, report, failures);
    return report;
}

// One read_async in progress: the blocks still to ask (a refused block's singles go first), and
// what the ones asked so far said.
struct DeviceClient::AsyncRead : std::enable_shared_from_this<AsyncRead> {
    struct Pending {
        ReadBlock block;
        bool may_split = false;
    };

    const DeviceClient& client;
    std::vector<const Parameter*> parameters;
    std::stop_token stop;
    ReadDone done;
    std::deque<Pending> pending;
    ReadReport report;
    Failures failures;
    std::optional<Error> stopped_by;

    AsyncRead(const DeviceClient& owner, std::vector<const Parameter*> wanted, std::stop_token stopping, ReadDone finished)
        : client(owner), parameters(std::move(wanted)), stop(std::move(stopping)), done(std::move(finished)) {}

    void next() {
        if (!stopped_by && stop.stop_requested()) stopped_by = make_error(ErrorKind::link, "polling stopped");
        if (stopped_by || pending.empty()) return finish();
        Pending asked = std::move(pending.front());
        pending.pop_front();
        auto request = client.read_request_of(asked.block);
        client.master_.execute_async(client.device_.unit, std::move(request),
                                     [self = shared_from_this(), asked = std::move(asked)](Result<codec::Reply> reply) mutable {
                                         self->filed(asked, std::move(reply));
                                     });
    }

    void filed(const Pending& asked, Result<codec::Reply> reply) {
        if (!reply && (reply.error().kind == ErrorKind::timeout || reply.error().kind == ErrorKind::link)) {
            stopped_by = reply.error();
        }
        if (!client.file_block(asked.block, std::move(reply), report, failures, asked.may_split)) {
            auto singles = client.split(asked.block);
            for (auto single = singles.rbegin(); single != singles.rend(); ++single) pending.push_front({std::move(*single), false});
        }
        next();
    }

    // The blocks never asked fail with what stopped the read.
    void finish() {
        for (const Pending& left : pending) {
            for (const Parameter* p : left.block.parameters) failures[p] = stopped_by->message;
        }
        pending.clear();
        client.decode_readings(parameters, report, failures);
        auto finished = std::move(done);
        finished(std::move(report), std::move(stopped_by));
    }
};

void DeviceClient::read_async(std::vector<const Parameter*> parameters, std::stop_token stop, ReadDone done) {
    auto read = std::make_shared<AsyncRead>(*this, std::move(parameters), std::move(stop), std::move(done));
    for (ReadBlock& block : plan(read->parameters)) {
        const bool may_split = block.parameters.size() > 1;
        read->pending.push_back({std::move(block), may_split});
    }
    read->next();
}

namespace {

// The parameters whose values tell whether one of `parameter`'s write modes holds; empty when
// some write mode has no requirement a master can check (it may hold: the device decides).
std::vector<std::string> mode_indicators(const Profile& profile, const Parameter& parameter) {
    std::vector<std::string> names;
    for (const auto& mode : parameter.write_modes) {
        auto requirement = profile.mode_requirements.find(mode);
        if (requirement == profile.mode_requirements.end()) return {};
        for (const auto& check : requirement->second) names.push_back(check.parameter);
    }
    return names;
}

bool requirements_hold(const std::vector<IdentificationCheck>& checks, const RawValues& known) {
    return std::all_of(checks.begin(), checks.end(), [&](const IdentificationCheck& check) {
        auto raw = known.find(check.parameter);
        return raw != known.end() && static_cast<std::int32_t>(raw->second) == check.equals;
    });
}

// A write the device would refuse in its present mode (AC20 in local: Note 5), said before
// anything is sent, with what to do about it.
Result<void> check_write_mode(const Profile& profile, const Parameter& parameter, const RawValues& known) {
    if (mode_indicators(profile, parameter).empty()) return {};
    std::vector<std::string> unmet;
    for (const auto& mode : parameter.write_modes) {
        const auto& checks = profile.mode_requirements.at(mode);
        if (requirements_hold(checks, known)) return {};
        for (const auto& check : checks) {
            const Parameter* indicator = profile.find(check.parameter);
            auto label = indicator ? indicator->enum_labels.find(check.equals) : std::map<std::int32_t, std::string>::const_iterator{};
            const std::string wanted = indicator && label != indicator->enum_labels.end() ? label->second : std::to_string(check.equals);
            unmet.push_back(fmt::format("{} needs {}={}", mode, check.parameter, wanted));
        }
    }
    return make_error(ErrorKind::usage, fmt::format("{} can be written only in {} mode, which {} is not in now ({}); set that first",
                                                    parameter.name, fmt::join(parameter.write_modes, " or "), profile.id,
                                                    fmt::join(unmet, "; ")));
}

}  // namespace

std::vector<const Parameter*> DeviceClient::needed_for(
    const std::vector<std::pair<const Parameter*, std::string>>& assignments) const {
    std::vector<const Parameter*> needed;
    for (const auto& [parameter, text] : assignments) {
        auto names = dependencies_of(*parameter);
        const auto indicators = mode_indicators(*device_.profile, *parameter);
        names.insert(names.end(), indicators.begin(), indicators.end());
        for (const auto& name : names) {
            if (const Parameter* dependency = device_.profile->find(name); dependency && dependency->readable) needed.push_back(dependency);
        }
    }
    return needed;
}

// Checked in order against the values as they will be by then: an earlier assignment can set
// the mode a later one needs (AC20 local_remote=remote main_set_point=0.9, Note 5).
Result<std::vector<PlannedWrite>> DeviceClient::plan_assignments(
    const std::vector<std::pair<const Parameter*, std::string>>& assignments, RawValues& known) const {
    std::vector<PlannedWrite> planned;
    for (const auto& [parameter, text] : assignments) {
        if (auto allowed = check_write_mode(*device_.profile, *parameter, known); !allowed) return allowed.error();
        auto raw = encode_value(*parameter, text, known);
        if (!raw) return raw.error();
        planned.push_back({parameter, *raw});
        known[parameter->name] = *raw;  // later bounds see the new value (TC10 SPLL before SP)
    }
    return planned;
}

Error DeviceClient::write_failure(const Error& error, const WriteReport& report) const {
    Error explained = explain(error);
    std::vector<std::string> done;
    for (const auto& [p, raw] : report.written) done.push_back(p->name);
    explained.message += fmt::format("; written before the failure: {}", done.empty() ? "nothing" : fmt::format("{}", fmt::join(done, ", ")));
    return explained;
}

Result<WriteReport> DeviceClient::write(const std::vector<std::pair<const Parameter*, std::string>>& assignments) {
    RawValues known;
    if (const auto needed = needed_for(assignments); !needed.empty()) {
        auto current = read(needed);
        if (current.first_error) return *current.first_error;
        known = std::move(current.raw);
    }
    auto planned = plan_assignments(assignments, known);
    if (!planned) return planned.error();
    auto report = write_raw(*planned);
    if (report) report->known = std::move(known);  // a unit word written here is known as written
    return report;
}

Result<WriteReport> DeviceClient::write_raw(const std::vector<PlannedWrite>& planned) {
    WriteReport report;
    for (const WriteBlock& block : plan_writes(*device_.profile, planned, device_.address_offset)) {
        ++report.requests;
        auto reply = master_.execute(device_.unit, write_request(block));
        if (!reply) return write_failure(reply.error(), report);
        for (std::size_t i = 0; i < block.parameters.size(); ++i) report.written.emplace_back(block.parameters[i], block.values[i]);
    }
    return report;
}

// One write_async in progress: the blocks still to write, and what was written so far.
struct DeviceClient::AsyncWrite : std::enable_shared_from_this<AsyncWrite> {
    AsyncWrite(DeviceClient& owner, WriteDone finished) : client(owner), done(std::move(finished)) {}

    void start(std::vector<std::pair<const Parameter*, std::string>> assignments) {
        auto needed = client.needed_for(assignments);
        if (needed.empty()) return checked(assignments);
        client.read_async(std::move(needed), {}, [self = shared_from_this(), assignments = std::move(assignments)](
                                                     ReadReport current, std::optional<Error>) {
            if (current.first_error) return self->end(*current.first_error);
            self->report.known = std::move(current.raw);
            self->checked(assignments);
        });
    }

    void checked(const std::vector<std::pair<const Parameter*, std::string>>& assignments) {
        auto planned = client.plan_assignments(assignments, report.known);
        if (!planned) return end(planned.error());
        for (WriteBlock& block : plan_writes(*client.device_.profile, *planned, client.device_.address_offset)) {
            blocks.push_back(std::move(block));
        }
        next();
    }

    void next() {
        if (blocks.empty()) return end(std::move(report));
        ++report.requests;
        client.master_.execute_async(client.device_.unit, write_request(blocks.front()),
                                     [self = shared_from_this()](Result<codec::Reply> reply) { self->written(std::move(reply)); });
    }

    void written(Result<codec::Reply> reply) {
        if (!reply) return end(client.write_failure(reply.error(), report));
        const WriteBlock& block = blocks.front();
        for (std::size_t i = 0; i < block.parameters.size(); ++i) report.written.emplace_back(block.parameters[i], block.values[i]);
        blocks.pop_front();
        next();
    }

    void end(Result<WriteReport> outcome) {
        auto finished = std::move(done);
        finished(std::move(outcome));
    }

    DeviceClient& client;
    WriteDone done;
    WriteReport report;  // `known`: the words checked against, as they are after the write
    std::deque<WriteBlock> blocks;
};

void DeviceClient::write_async(std::vector<std::pair<const Parameter*, std::string>> assignments, WriteDone done) {
    std::make_shared<AsyncWrite>(*this, std::move(done))->start(std::move(assignments));
}

}  // namespace loopwire::device
