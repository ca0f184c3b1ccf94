#pragma once
// A link to devices, opened from the URL the command line takes.
#include <chrono>
#include <memory>
#include <string>

namespace loopwire {

struct LinkOptions {
    std::chrono::milliseconds timeout{1000};  // per try
    unsigned retries = 0;                     // extra tries after a timeout (or a reply refused as a probable copy)
};

class Link {
public:
    // Opens "rtu:/dev/ttyUSB0?baud=19200&parity=even", "ascii:...", "linking:...",
    // "tcp://127.0.0.1:1502" or "rtu+tcp://host:4001". Throws Failure: Kind::usage for a
    // malformed URL, Kind::link when the port or connection cannot be opened.
    static Link open(const std::string& url, const LinkOptions& options = {});

    // What the link is, for messages: the port or peer and its settings.
    std::string describe() const;

    // Copies share the one open link; it closes when the last copy (or Device on it) goes.
    struct State;

private:
    explicit Link(std::shared_ptr<State> state);
    std::shared_ptr<State> state_;
    friend class Device;
};

}  // namespace loopwire
