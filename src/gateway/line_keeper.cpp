#include "gateway/line_keeper.hpp"

#include <algorithm>

#include "session/line_loop.hpp"
#include "simulation/simulated_lines.hpp"

namespace loopwire::gateway {
namespace {

bool same_units(const std::vector<DeviceConfig>& a, const std::vector<DeviceConfig>& b) {
    return std::equal(a.begin(), a.end(), b.begin(), b.end(),
                      [](const DeviceConfig& x, const DeviceConfig& y) { return x.address == y.address; });
}

std::vector<const LineConfig*> simulated(const std::vector<LineConfig>& all) {
    std::vector<const LineConfig*> lines;
    for (const auto& line : all) {
        if (line.simulation) lines.push_back(&line);
    }
    return lines;
}

}  // namespace

bool line_kept_as(const LineConfig& running, const LineConfig& next) {
    const bool carried_alike = running.name == next.name && running.link == next.link && running.simulation == next.simulation &&
                               running.timeout == next.timeout && running.retries == next.retries &&
                               running.late_reply_window == next.late_reply_window &&
                               running.max_in_flight == next.max_in_flight;
    return carried_alike && (!running.simulation || same_units(running.devices, next.devices));
}

bool simulations_kept_as(const std::vector<LineConfig>& running, const std::vector<LineConfig>& next) {
    const auto before = simulated(running);
    const auto after = simulated(next);
    return std::equal(before.begin(), before.end(), after.begin(), after.end(),
                      [](const LineConfig* a, const LineConfig* b) { return line_kept_as(*a, *b); });
}

LineKeeper::LineKeeper() : loop_(std::make_shared<session::LineLoop>()) {}

LineKeeper::~LineKeeper() { close_untaken(); }

void LineKeeper::keep(OpenLine line) { lines_.push_back(std::move(line)); }

std::optional<OpenLine> LineKeeper::take(const LineConfig& config) {
    const auto found = std::find_if(lines_.begin(), lines_.end(), [&](const OpenLine& line) { return line_kept_as(line.config, config); });
    if (found == lines_.end()) return std::nullopt;
    OpenLine taken = std::move(*found);
    lines_.erase(found);
    taken.config = config;
    taken.scheduler->resume();
    return taken;
}

// As a gateway closes its lines: the master first, so that a request on the wire ends now.
void LineKeeper::close_untaken() {
    for (const auto& line : lines_) line.master->close();
    lines_.clear();
}

}  // namespace loopwire::gateway
