#pragma once
// The lines a gateway hands to the next one across a reload (SIGHUP keeps what
// did not change). A line whose configuration the reload leaves alone stays open: its port is
// not closed and reopened, its scheduler keeps its back-offs and statistics, the request on its
// wire is not cut short, and the next gateway's polls go on where the last ones stopped. Kept by
// the caller across rounds (gateway/service.hpp), like the Modbus TCP front, with the loop that
// carries the lines: the thread count stays what it was.
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "gateway/gateway_config.hpp"
#include "gateway/line_scheduler.hpp"
#include "gateway/reopening_master.hpp"

namespace loopwire::session {
class LineLoop;
}
namespace loopwire::simulation {
class SimulatedLines;
}

namespace loopwire::gateway {

// One line as a gateway runs it.
struct OpenLine {
    LineConfig config;  // what it was opened with
    std::string link;   // config.link as text, for reports
    std::shared_ptr<std::atomic<std::uint64_t>> garbled;  // counted from the master's trace
    // Held here as well as by the scheduler, and declared first so that it goes last: the
    // master joins its own thread when destroyed, which must not be the thread that destroys the
    // scheduler from a completion (line_scheduler.hpp, ownership).
    std::shared_ptr<ReopeningMaster> master;
    std::shared_ptr<LineScheduler> scheduler;
};

// Whether a line opened as `running` can serve as `next`: the same name, link and timing, and
// for a simulated line the same devices at the same units (its simulation serves them). A real
// port does not care which devices are polled on it.
bool line_kept_as(const LineConfig& running, const LineConfig& next);

// Whether the simulated lines of `running` can all be kept for `next`: they share one
// simulation (simulation::SimulatedLines), which serves every one of them or none.
bool simulations_kept_as(const std::vector<LineConfig>& running, const std::vector<LineConfig>& next);

class LineKeeper {
public:
    LineKeeper();
    // Closes the lines no gateway took, then lets the loop go.
    ~LineKeeper();
    LineKeeper(const LineKeeper&) = delete;
    LineKeeper& operator=(const LineKeeper&) = delete;

    // The loop every gateway's lines run on, made with the first.
    const std::shared_ptr<session::LineLoop>& loop() const { return loop_; }
    // The simulated lines' devices, shared by the gateways that keep them; a gateway that does
    // not keep them makes new ones here.
    std::shared_ptr<simulation::SimulatedLines>& simulations() { return simulations_; }

    // From a gateway going away for a reload: `line`, its scheduler already handed over.
    void keep(OpenLine line);
    // For the next gateway: the kept line that can serve as `config`, resumed, if there is one.
    std::optional<OpenLine> take(const LineConfig& config);
    // Lines no gateway took: closed. The next gateway calls it once it has taken its own.
    void close_untaken();
    std::size_t kept() const { return lines_.size(); }

private:
    std::shared_ptr<session::LineLoop> loop_;
    std::shared_ptr<simulation::SimulatedLines> simulations_;
    std::vector<OpenLine> lines_;
};

}  // namespace loopwire::gateway
