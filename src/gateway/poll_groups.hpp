#pragma once
// The gateway's own polling. Devices polled at the same interval form a poll group; each group
// runs the client's poller (client/monitor_loop.hpp) on its own thread, through the lines'
// schedulers at poll priority, so polls take the line only when no write or client waits.
// What each poll finds goes into the value cache (gateway/value_cache.hpp), and a device that
// stops or starts answering is logged.
#include <chrono>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "client/monitor_loop.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/gateway_config.hpp"
#include "gateway/scheduled_master.hpp"
#include "gateway/value_cache.hpp"

namespace loopwire::gateway {

class PollGroups {
public:
    // `lines`: the scheduler of each configured line, by line name. `also`, when given, gets
    // every sample too, on the group's thread.
    PollGroups(const GatewayConfig& config, const std::map<std::string, std::shared_ptr<LineScheduler>>& lines,
               ValueCache& cache, GatewayLog log, device::SampleSink* also = nullptr);
    ~PollGroups();  // stops every group; a poll on the wire is finished first
    PollGroups(const PollGroups&) = delete;
    PollGroups& operator=(const PollGroups&) = delete;

    std::size_t size() const { return groups_.size(); }

private:
    struct Group;
    std::vector<std::unique_ptr<Group>> groups_;
};

}  // namespace loopwire::gateway
