#include "gateway/poll_groups.hpp"

#include <algorithm>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <set>
#include <utility>

#include <fmt/format.h>

namespace loopwire::gateway {
namespace {

// A group that fell behind is said to keep its interval again only after this many samples on
// time in a row: a line at the edge of its capacity is one warning, not one per sample.
constexpr unsigned samples_on_time_to_recover = 10;

std::string joined(const std::vector<std::string>& names) {
    std::string text;
    for (const auto& name : names) text += (text.empty() ? "" : ", ") + name;
    return text;
}

// Hands each sample of one group to the cache, and logs a device whose answering changes: the
// first answer, a silence ("no-reply"), an answer again, and the group falling behind its
// interval or keeping it again. Nothing per sample: the log is read by people.
class CachingSink final : public device::SampleSink {
public:
    CachingSink(std::chrono::milliseconds interval, std::vector<std::string> names, std::vector<std::string> lines,
                ValueCache& cache, GatewayLog log, device::SampleSink* also)
        : interval_(interval), names_(std::move(names)), lines_(std::move(lines)), answering_(names_.size()),
          cache_(cache), log_(std::move(log)), also_(also) {}

    void write(const device::SampleView& sample) override {
        const auto& devices = *sample.devices;
        for (std::size_t i = 0; i < devices.size() && i < names_.size(); ++i) {
            cache_.update(names_[i], devices[i], sample.time);
            note_answering(i, devices[i]);
        }
        note_pace(sample.missed);
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

    void note_pace(unsigned missed) {
        if (missed > 0) {
            on_time_ = 0;
            if (!std::exchange(behind_, true) && log_) {
                log_(fmt::format("warning: the polls every {} ms of {} fall behind: a sample took longer than the interval "
                                 "and the next {} skipped; line {} cannot carry these polls beside the other requests at "
                                 "this rate (poll less often, read fewer parameters, or give the devices a line of their "
                                 "own; /metrics: loopwire_line_polls_missed_total)",
                                 interval_.count(), joined(names_), missed == 1 ? "was" : fmt::format("{} were", missed),
                                 joined(lines_)));
            }
            return;
        }
        if (behind_ && ++on_time_ >= samples_on_time_to_recover) {
            behind_ = false;
            if (log_) log_(fmt::format("the polls every {} ms of {} keep their interval again", interval_.count(), joined(names_)));
        }
    }

    std::chrono::milliseconds interval_;
    std::vector<std::string> names_;
    std::vector<std::string> lines_;  // the lines the group's devices are on, each once
    std::vector<std::optional<bool>> answering_;
    ValueCache& cache_;
    GatewayLog log_;
    device::SampleSink* also_;
    bool behind_ = false;
    unsigned on_time_ = 0;
};

// Until `stop`: every `tick`, the cache marks the overdue devices stale, and each device going
// stale or fresh again is logged once.
void watch_staleness(ValueCache& cache, std::chrono::milliseconds tick, const GatewayLog& log, const std::stop_token& stop) {
    std::set<std::string> stale;
    std::mutex mutex;
    std::condition_variable_any woken;
    std::unique_lock lock(mutex);
    while (!woken.wait_for(lock, stop, tick, [] { return false; }) && !stop.stop_requested()) {
        const auto now_list = cache.mark_overdue();
        const std::set<std::string> now(now_list.begin(), now_list.end());
        if (!log) {
            stale = now;
            continue;
        }
        for (const auto& name : now) {
            if (!stale.count(name)) {
                log(fmt::format("warning: device {} is stale: its poll is more than {} intervals overdue, so its values "
                                "read \"stale\" until a poll reads them again",
                                name, overdue_intervals_allowed));
            }
        }
        for (const auto& name : stale) {
            if (!now.count(name)) log(fmt::format("device {} is polled again: its values are current", name));
        }
        stale = now;
    }
}

}  // namespace

std::chrono::milliseconds staleness_tick(std::chrono::milliseconds shortest_interval) {
    return std::clamp(shortest_interval / 4, std::chrono::milliseconds(50), std::chrono::milliseconds(1000));
}

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
    std::map<std::chrono::milliseconds, std::vector<std::string>> group_lines;
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
            auto& on = group_lines[device.poll];
            if (std::find(on.begin(), on.end(), line.name) == on.end()) on.push_back(line.name);
            cache.expect_polls(device.name, device.poll);
        }
    }
    for (auto& [interval, group] : by_interval) {
        group->settings.interval = interval;
        group->sink = std::make_unique<CachingSink>(interval, std::move(names[interval]), std::move(group_lines[interval]), cache,
                                                    log, also);
        group->thread = std::jthread([g = group.get()](std::stop_token stop) {
            device::run_monitor(g->targets, g->settings, *g->sink, std::move(stop));
        });
        groups_.push_back(std::move(group));
    }
    if (by_interval.empty()) return;
    const auto tick = staleness_tick(by_interval.begin()->first);
    staleness_ = std::jthread([&cache, tick, log = std::move(log)](std::stop_token stop) { watch_staleness(cache, tick, log, stop); });
}

PollGroups::~PollGroups() = default;

}  // namespace loopwire::gateway
