#pragma once
// What `loopwire decode` says about one frame, independent of how it is printed.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/bytes.hpp"
#include "common/result.hpp"

namespace loopwire::app {

struct FrameExplanation {
    std::string protocol;
    std::optional<unsigned> unit;
    std::optional<unsigned> transaction;   // tcp
    std::optional<unsigned> function;
    std::optional<std::string> command;    // linking: "R", "M", "W"
    std::string kind;                       // "request", "reply", "exception"
    std::optional<unsigned> address;
    std::optional<unsigned> count;
    std::vector<std::uint16_t> values;
    std::optional<unsigned> exception;
    bool check_ok = false;
    std::string problem;                    // empty for a valid frame
};

// `direction` "" tries a request first, then a reply. Errors only for a bad protocol name.
Result<FrameExplanation> explain_frame(const std::string& protocol, const std::string& direction, ByteView wire);

nlohmann::ordered_json to_json(const FrameExplanation& explanation);

}  // namespace loopwire::app
