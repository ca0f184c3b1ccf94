#pragma once
// What framers hand out: one delimited frame, or a run of bytes that had to be thrown away.
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "common/bytes.hpp"

namespace loopwire::codec {

// A serial-line or TCP application data unit, reduced to what sessions need.
struct Frame {
    std::uint8_t unit = 0;
    Bytes pdu;                       // function code + data, check bytes removed
    std::uint16_t transaction = 0;   // MBAP transaction id (TCP only)
    Bytes raw;                       // the bytes as they came off the wire, for -v traces

    bool operator==(const Frame&) const = default;
};

// Bytes a decoder discarded while resynchronising (noise, bad check, truncated frame).
struct DiscardedBytes {
    Bytes bytes;
    std::string reason;  // "CRC mismatch: computed 64 05, received 00 00", "gap inside frame", ...
};

using FrameEvent = std::variant<Frame, DiscardedBytes>;
using FrameEvents = std::vector<FrameEvent>;

}  // namespace loopwire::codec
