#pragma once
// `loopwire dump`: one device's readable parameters as a self-describing JSON document, the
// input of `loopwire restore`. The format is stable; a change that breaks readers bumps version.
//
//   {"format":"loopwire-dump","version":1,
//    "profile":"tc10","unit":3,"link":"rtu:/dev/ttyUSB0","time":"2026-11-23T09:31:02.123Z",
//    "identification":{"instrument_id":20,...},      // profile identification report: raw words
//    "parameters":{
//      "set_point":{"value":250.0,"text":"250.0","unit":"°C","raw":[2500],"status":"ok","writable":true},
//      ...}}
//
// Per parameter, in the profile's order: "value" a number, an enum label, an object of named
// bits, or null for a special state; "text" the value as `loopwire write NAME=TEXT` accepts it
// back (numbers with the parameter's decimals, labels, special state names, bits joined by '+');
// "raw" the words read, first word first; "status" "ok", a special state or "unknown-label",
// "unread" (value, text null, raw empty) with "error" the device's refusal, or "undecodable"
// (value, text null, raw the word read) with "error" why it could not be decoded (e.g. the
// AC20 word 300 holding the decimals reads 0xFFFF); "writable"
// whether a restore may write it. "numbering" is present when the device uses an
// alternative numbering (ac20: "jbus").
#include <string>

#include <nlohmann/json.hpp>

#include "common/result.hpp"
#include "client/device_client.hpp"

namespace loopwire::device {

struct DumpHeader {
    std::string link;
    std::string time;       // ISO 8601 UTC
    std::string numbering;  // empty: the profile's own
};

// Every readable parameter of the profile, hidden ones included: a dump records the device.
std::vector<const device::Parameter*> dumped_parameters(const device::Profile& profile);

// The document from a read; a parameter not read is an "unread" entry with its reason (the
// dump command decides which refusals a dump may carry), a word read that cannot be decoded
// or turned into text an "undecodable" entry with its reason.
Result<nlohmann::ordered_json> dump_document(const device::DeviceAddress& device, const DumpHeader& header,
                                             const device::ReadReport& report);

}  // namespace loopwire::device
