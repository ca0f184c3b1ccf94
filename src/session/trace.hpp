#pragma once
// What `-v` shows: every frame sent and received, as hex with a timestamp, and every run of
// bytes thrown away with the reason. People debugging a line need this first.
#include <functional>
#include <string>

#include "common/bytes.hpp"

namespace loopwire::session {

enum class TraceDirection { sent, received, discarded };

struct TraceEvent {
    Instant at;
    TraceDirection direction;
    Bytes bytes;
    std::string note;  // "unit 7 read holding registers", discard reason, ...
};

using TraceSink = std::function<void(const TraceEvent&)>;

}  // namespace loopwire::session
