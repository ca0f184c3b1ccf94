#pragma once
// Reads and writes one device by parameter name, in engineering units, over any master: the
// request planner decides the requests, the value codecs turn words into values.
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <stop_token>
#include <memory>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "profile/profile.hpp"
#include "profile/profile_registry.hpp"
#include "profile/request_planner.hpp"
#include "profile/values.hpp"
#include "session/master.hpp"

namespace loopwire::device {

// "tc10@3": a profile and the unit id it answers at.
struct DeviceAddress {
    std::shared_ptr<const Profile> profile;
    std::uint8_t unit = 1;
    int address_offset = 0;  // numbering alternative in use (AC20 J-BUS: +1)
};

// "DEVICE@UNIT" taken apart without looking the id up: the unit must be 1..255 (1 when no
// '@' is given); parse_device_address then holds it to the profile's unit_ids.
struct DeviceName {
    std::string id;
    std::uint8_t unit = 1;
};
Result<DeviceName> split_device_address(const std::string& text);

// Parses "DEVICE@UNIT" against the profiles of `profiles`; `numbering` names an alternative
// numbering of the profile ("jbus") or is empty for the profile's own.
Result<DeviceAddress> parse_device_address(const ProfileRegistry& profiles, const std::string& text,
                                           const std::string& numbering = {});
// The same against the built-in profiles only (no profile files).
Result<DeviceAddress> parse_device_address(const std::string& text, const std::string& numbering = {});

struct ParameterReading {
    const Parameter* parameter = nullptr;
    std::optional<EngineeringValue> value;  // absent when the read failed
    std::string error;                      // why, when it failed
};

struct ReadReport {
    std::vector<ParameterReading> readings;  // in the order asked
    RawValues raw;                           // every word read, dependencies included
    unsigned requests = 0;
    std::optional<Error> first_error;        // the first failed request, if any
};

struct WriteReport {
    std::vector<std::pair<const Parameter*, std::uint16_t>> written;
    unsigned requests = 0;
    // The words the values were checked against (decimals, bounds, unit words), as they are
    // after the write: what unit_of needs to show a written value in the unit a read would.
    RawValues known;
};

// The end of a read_async: the report, and the timeout or link failure that ended it early.
using ReadDone = std::function<void(ReadReport report, std::optional<Error> stopped_by)>;

// The built-in profile whose identification words all hold at `unit`, as DEVICE@UNIT, if any:
// what `loopwire scan` names a unit by, and what a refused identification says is there.
std::optional<DeviceAddress> identify_unit(session::Master& master, int unit);

class DeviceClient {
public:
    DeviceClient(session::Master& master, DeviceAddress device);

    // Reads `parameters` and whatever their values depend on (decimals from other words), in
    // planned blocks. A failed block marks its parameters as failed; the others are still read.
    ReadReport read(const std::vector<const Parameter*>& parameters);
    // As read, and the words that bound the values too (a TC10's SP.LL and SP.HL for its SP), so
    // their limits resolve (limits_of over the report's words): what one-shot reads by name show.
    // Polls leave them out and read them on a slower schedule of their own (gateway/poll_groups).
    ReadReport read_with_limits(const std::vector<const Parameter*>& parameters);

    // The same without blocking, for a poller on an event loop: the blocks go one after another
    // by the master's execute_async, each from the completion of the one before, and `done` runs
    // once, on the thread of the last completion (or the caller's, when the master answers at
    // once). A poll's rule: the first block that times out or finds the link failed ends the read
    // (`stopped_by`), its other blocks failed with the same error unsent, so a silent device
    // costs one timeout. A requested `stop` also ends it before the next block. The client (and
    // its master) must live until `done` has run.
    void read_async(std::vector<const Parameter*> parameters, std::stop_token stop, ReadDone done);

    // Validates every value first (access, type, decimals, range — bounds by other parameters
    // are read from the device), then writes in planned blocks, in the order given. Nothing is
    // sent when any value is invalid. Stops at the first failed request and says which
    // parameters were and were not written.
    Result<WriteReport> write(const std::vector<std::pair<const Parameter*, std::string>>& assignments);

    // The same without blocking, as read_async: the words the checks need are read first
    // (read_async's rules), then the planned blocks are written one after another from each
    // completion. `done` runs once, on the thread of the last completion or the caller's. The
    // client must live until it has run.
    using WriteDone = std::function<void(Result<WriteReport>)>;
    void write_async(std::vector<std::pair<const Parameter*, std::string>> assignments, WriteDone done);

    // Writes raw words as they are (restore: values read from the device before), in planned
    // blocks in the order given, checking nothing first. Stops at the first failed request and
    // says which parameters were and were not written.
    Result<WriteReport> write_raw(const std::vector<PlannedWrite>& writes);

    // Whether the device at the unit is the one the profile describes: its identification words
    // (the profile's "identification.match", which `loopwire scan` uses too) read what they
    // must. A mismatch error says what was found and how to tell what the device is; a timeout
    // or link failure is returned as it is. A profile without identification words passes.
    Result<void> confirm_identity();

    // The profile's meaning of an exception code, if it names one ("AC20: ...").
    Error explain(Error error) const;

    const DeviceAddress& device() const { return device_; }

private:
    struct AsyncRead;
    using Failures = std::map<const Parameter*, std::string>;

    codec::Request read_request_of(const ReadBlock& block) const;
    std::vector<ReadBlock> plan(const std::vector<const Parameter*>& parameters) const;
    ReadReport read_planned(const std::vector<const Parameter*>& parameters, const std::vector<ReadBlock>& blocks);
    std::vector<ReadBlock> split(const ReadBlock& block) const;
    // Files one block's reply. false: the device refused the block with an exception and
    // `may_split` was set (the caller splits it); otherwise the block's values or failures are
    // in the report.
    bool file_block(const ReadBlock& block, Result<codec::Reply> reply, ReadReport& report, Failures& failures,
                    bool may_split) const;
    void decode_readings(const std::vector<const Parameter*>& parameters, ReadReport& report, const Failures& failures) const;
    struct AsyncWrite;
    // What a write's values are checked against: decimals and range bounds held by other words,
    // and the words that tell the device's mode.
    std::vector<const Parameter*> needed_for(const std::vector<std::pair<const Parameter*, std::string>>& assignments) const;
    // The words to write, each value checked against `known` as it will be by then.
    Result<std::vector<PlannedWrite>> plan_assignments(const std::vector<std::pair<const Parameter*, std::string>>& assignments,
                                                       RawValues& known) const;
    Error write_failure(const Error& error, const WriteReport& report) const;

    session::Master& master_;
    DeviceAddress device_;
};

}  // namespace loopwire::device
