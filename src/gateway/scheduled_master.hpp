#pragma once
// A master that queues on a line's scheduler instead of owning the line: what the gateway's own
// polling (the device client and poller of client/) talks to, so polls take their turn after
// writes and clients' requests (line_scheduler.hpp).
#include <memory>

#include "gateway/line_scheduler.hpp"
#include "session/master.hpp"

namespace loopwire::gateway {

class ScheduledMaster final : public session::Master {
public:
    // `request_limit`: how long a request may wait for the line before it is dropped unsent.
    ScheduledMaster(std::shared_ptr<LineScheduler> line, std::string name, Priority priority,
                    std::chrono::milliseconds request_limit, std::shared_ptr<Clock> clock = steady_clock());

    Result<codec::Reply> execute(std::uint8_t unit, const codec::Request& request) override;
    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override;
    Result<Bytes> forward(std::uint8_t unit, ByteView pdu) override;
    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override;
    std::string describe() const override { return name_; }

private:
    std::shared_ptr<LineScheduler> line_;
    std::string name_;
    Priority priority_;
    std::chrono::milliseconds request_limit_;
    std::shared_ptr<Clock> clock_;
};

}  // namespace loopwire::gateway
