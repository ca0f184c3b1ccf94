#include "gateway/poll_groups.hpp"

#include <optional>

#include <fmt/format.h>

namespace loopwire::gateway {
namespace {

// Hands each sample of one group to the cache, and logs a device whose answering changes: the
// first answer, a silence ("no-reply"), an answer again. Nothing per sample: the log is read by
// people.
class CachingSink final : public device::SampleSink {
public:
    CachingSink(std::vector<std::string> names, ValueCache& cache, GatewayLog log, device::SampleSink* also)
        : names_(std::move(names)), answering_(names_.size()), cache_(cache), log_(std::move(log)), also_(also) {}

    void write(const device::SampleView& sample) override {
        const auto& devices = *sample.devices;
        for (std::size_t i = 0; i < devices.size() && i < names_.size(); ++i) {
            cache_.update(names_[i], devices[i], sample.time);
            note_answering(i, devices[i]);
        }
        if (also_) also_->write(sample);
    }

private:
    void note_answering(std::size_t i, const device::WatchedDevice& device) {
        // Not polled this time, or the poll could not reach it (the line logs that itself):
        // nothing new about whether the device answers.
        if (device.status == "waiting" || device.status == "line-down") return;
        const bool answers = device.status != "no-reply";
        if (answering_[i] == answers) return;
        const bool first = !answering_[i].has_value();
        answering_[i] = answers;
        if (!log_) return;
        if (answers) {
            log_(fmt::format("device {} ({}) {}", names_[i], device.label, first ? "answers" : "answers again"));
        } else {
            log_(fmt::format("device {} ({}) does not answer: {}; polled again with back-off", names_[i], device.label, device.last_error));
        }
    }

    std::vector<std::string> names_;
    std::vector<std::optional<bool>> answering_;
    ValueCache& cache_;
    GatewayLog log_;
    device::SampleSink* also_;
};

}  // namespace

struct PollGroups::Group {
    std::vector<std::unique_ptr<ScheduledMaster>> masters;  // one per device: each names its line
    std::vector<device::MonitorTarget> targets;
    std::unique_ptr<CachingSink> sink;
    device::MonitorSettings settings;
    std::jthread thread;  // last: stops and joins before the rest goes
};

PollGroups::PollGroups(const GatewayConfig& config, const std::map<std::string, std::shared_ptr<LineScheduler>>& lines,
                       ValueCache& cache, GatewayLog log, device::SampleSink* also) {
    std::map<std::chrono::milliseconds, std::unique_ptr<Group>> by_interval;
    std::map<std::chrono::milliseconds, std::vector<std::string>> names;
    for (const auto& line : config.lines) {
        const auto& scheduler = lines.at(line.name);
        for (const auto& device : line.devices) {
            auto& group = by_interval[device.poll];
            if (!group) group = std::make_unique<Group>();
            // A poll waiting longer than its interval would only be stale when it came back.
            group->masters.push_back(std::make_unique<ScheduledMaster>(scheduler, line.link.to_string(), Priority::poll, device.poll));
            // The unit's back-off is the scheduler's (line_scheduler.hpp); the poller defers to it.
            const std::uint8_t unit = device.address.unit;
            group->targets.push_back({group->masters.back().get(), device.address, polled_parameters(device),
                                      [scheduler, unit] { return scheduler->hold_poll(unit); }});
            names[device.poll].push_back(device.name);
        }
    }
    for (auto& [interval, group] : by_interval) {
        group->settings.interval = interval;
        group->sink = std::make_unique<CachingSink>(std::move(names[interval]), cache, log, also);
        group->thread = std::jthread([g = group.get()](std::stop_token stop) {
            device::run_monitor(g->targets, g->settings, *g->sink, std::move(stop));
        });
        groups_.push_back(std::move(group));
    }
}

PollGroups::~PollGroups() = default;

}  // namespace loopwire::gateway
