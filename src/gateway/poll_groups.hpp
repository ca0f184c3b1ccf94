#pragma once
// The gateway's own polling. Devices on one line polled at the same interval form a poll group.
// Every group runs on the gateway's event loop (gateway/engine.hpp; any EventLoop, whose clock
// the polls and their staleness watch keep time by: virtual in tests), however many devices and
// intervals there are: a timer starts each sample on the fixed schedule of the client's poller
// (client/monitor_loop.hpp), its devices are read at once without blocking
// (DeviceClient::read_async), each through its line's scheduler at poll priority, where polls
// share the line with the clients' requests by turns (line_scheduler.hpp). A sample ends when all
// its devices have answered or failed, and the next waits for that: groups are per line so that
// a silent device or a slow line delays no other line's polls. What each poll finds goes into the
// value cache (gateway/value_cache.hpp) as its reply comes, stamped with the loop's wall time
// then, and a device that stops or starts answering is logged.
//
// Polls that cannot keep their rate are reported two ways. A group whose sample ran past its
// interval (its line cannot carry its polls beside everything else) is logged once when it
// falls behind and once when it keeps its interval again, and its skipped samples are counted
// in each device's `missed` (/metrics). And a timer on the same loop, a quarter of the shortest
// interval (50 ms to 1 s), has the cache mark the devices whose poll is overdue `stale`, since
// a poll stuck on its line reports nothing itself; each device going stale or fresh is logged.
#include <chrono>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "client/monitor_loop.hpp"
#include "gateway/event_loop.hpp"
#include "gateway/forwarding_unit.hpp"
#include "gateway/gateway_config.hpp"
#include "gateway/scheduled_master.hpp"
#include "gateway/value_cache.hpp"

namespace loopwire::gateway {

class PollGroups {
public:
    // `lines`: the scheduler of each configured line, by line name. `also`, when given, gets
    // every sample too, on the polls' thread.
    // `loop`: what the groups run on (the gateway's Engine; a LineLoopEvents in virtual-time tests).
    PollGroups(EventLoop& loop, const GatewayConfig& config, const std::map<std::string, std::shared_ptr<LineScheduler>>& lines,
               ValueCache& cache, GatewayLog log, device::SampleSink* also = nullptr);
    ~PollGroups();  // stops every group; a poll on the wire is finished first
    PollGroups(const PollGroups&) = delete;
    PollGroups& operator=(const PollGroups&) = delete;

    std::size_t size() const { return size_; }

    // A front wrote these parameters (profile names) of the device (its configured name): where
    // one bounds a polled value (a TC10's SP.HL for its SP), the device's next poll reads its
    // bounding words again, so every front shows the new limit then, not at the 5-minute
    // refresh. On the engine's loop (DeviceWriter::on_written).
    void written(const std::string& device, const std::vector<std::string>& parameters);
    // The same for a write whose parameters are not known (a Modbus TCP client's raw registers):
    // the device's next poll reads every bounding word again.
    void written_unknown(const std::string& device);

private:
    struct Group;
    struct State;
    // Has the device's next poll read its bounds again where one of them is `moved`.
    void refresh_limits_of(const std::string& device, const std::function<bool(const device::Parameter&)>& moved);
    std::unique_ptr<State> state_;
    std::size_t size_ = 0;
};

// How often the staleness timer looks: a quarter of the shortest poll interval, kept within
// 50 ms (no busy loop for fast polls) and 1 s (a slow poll's staleness is still told promptly).
std::chrono::milliseconds staleness_tick(std::chrono::milliseconds shortest_interval);

}  // namespace loopwire::gateway
