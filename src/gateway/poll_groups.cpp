#include "gateway/poll_groups.hpp"

#include <algorithm>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <set>
#include <stop_token>
#include <utility>

#include <fmt/format.h>

#include "client/device_status.hpp"

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

// How often the words that bound the polled values (a TC10's SP.LL and SP.HL) are read again
// beside a poll: limits are configuration, changed by hand now and then, and reading them with
// every sample would cost the AC20 a request more per poll (its limits are far from its values).
constexpr auto limits_refresh = std::chrono::minutes(5);

// The readable words that bound the polled parameters and are not polled themselves.
std::vector<const device::Parameter*> bound_words(const device::Profile& profile,
                                                  const std::vector<const device::Parameter*>& polled) {
    std::vector<const device::Parameter*> words;
    for (const device::Parameter* parameter : polled) {
        for (const auto& bound : {parameter->min, parameter->max}) {
            const auto* name = bound ? std::get_if<std::string>(&*bound) : nullptr;
            const device::Parameter* word = name ? profile.find(*name) : nullptr;
            if (!word || !word->readable) continue;
            if (std::find(polled.begin(), polled.end(), word) != polled.end()) continue;
            if (std::find(words.begin(), words.end(), word) == words.end()) words.push_back(word);
        }
    }
    return words;
}

// Hands each sample of one group to the cache, and logs a device whose answering changes: the
// first answer, a silence ("no-reply"), an answer again, and the group falling behind its
// interval or keeping it again. Nothing per sample: the log is read by people.
//
// Each device's changes are stamped with when its reply came (polled), not when its sample
// started: a sample's start could lie before a `stale` found while the reply was awaited, and
// the history then filed the reply before the stale row (the cache keeps a device's stamps in
// order too, value_cache.hpp).
class CachingSink final : public device::SampleSink {
public:
    CachingSink(std::chrono::milliseconds interval, std::vector<std::string> names, std::vector<std::string> lines,
                ValueCache& cache, GatewayLog log, device::SampleSink* also)
        : interval_(interval), names_(std::move(names)), lines_(std::move(lines)), answering_(names_.size()),
          cache_(cache), log_(std::move(log)), also_(also) {}

    // Device `i`'s poll ended at `replied`, the loop's wall time.
    void polled(std::size_t i, std::chrono::system_clock::time_point replied) {
        if (replied_.size() < names_.size()) replied_.resize(names_.size());
        if (i < replied_.size()) replied_[i] = replied;
    }

    void write(const device::SampleView& sample) override {
        const auto& devices = *sample.devices;
        for (std::size_t i = 0; i < devices.size() && i < names_.size(); ++i) {
            const bool stamped = i < replied_.size() && replied_[i];
            cache_.update(names_[i], devices[i], stamped ? *replied_[i] : sample.time);
            note_answering(i, devices[i]);
        }
        replied_.clear();
        note_pace(sample.missed);
        if (also_) also_->write(sample);
    }

private:
    void note_answering(std::size_t i, const device::WatchedDevice& device) {
        // Not polled this time, or the poll could not reach it (the line logs that itself):
        // nothing new about whether the device answers.
        if (!device::polled(device.status) || device.status == device::DeviceStatus::line_down) return;
        note_identity(i, device);
        const bool answers = device.status != device::DeviceStatus::no_reply;
        if (answering_[i] == answers) return;
        const bool first = !answering_[i].has_value();
        answering_[i] = answers;
        if (!log_) return;
        if (answers) {
            // Answering again ends the warning that said it did not: a notice.
            log_(first ? fmt::format("device {} ({}) answers", names_[i], device.label)
                       : fmt::format("notice: device {} ({}) answers again", names_[i], device.label));
        } else {
            // A warning (GatewayLog): what a person reading `journalctl -p warning` must see.
            log_(fmt::format("warning: device {} ({}) does not answer: {}; polled again with back-off", names_[i], device.label,
                             device.last_error));
        }
    }

    // A unit found to answer as another device is said once, until it is found to be the device.
    void note_identity(std::size_t i, const device::WatchedDevice& device) {
        if (wrong_.size() < names_.size()) wrong_.resize(names_.size());
        const bool wrong = device.status == device::DeviceStatus::wrong_device;
        if (wrong_[i] == wrong || (!wrong && !device.identity_confirmed)) return;
        wrong_[i] = wrong;
        if (!log_) return;
        if (wrong) {
            log_(fmt::format("warning: device {} ({}): {}; its values are not kept until it answers as {} (or set identify = "
                             "false on the device to take it as it is)",
                             names_[i], device.label, device.last_error, device.label));
        } else {
            // Said only after it answered as another: the end of that warning, a notice.
            log_(fmt::format("notice: device {} ({}) is identified", names_[i], device.label));
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
            if (log_) log_(fmt::format("notice: the polls every {} ms of {} keep their interval again", interval_.count(), joined(names_)));
        }
    }

    std::chrono::milliseconds interval_;
    std::vector<std::string> names_;
    std::vector<std::string> lines_;  // the lines the group's devices are on, each once
    std::vector<std::optional<bool>> answering_;
    std::vector<bool> wrong_;  // by device: whether it was last found answering as another
    std::vector<std::optional<std::chrono::system_clock::time_point>> replied_;  // this sample's, by device
    ValueCache& cache_;
    GatewayLog log_;
    device::SampleSink* also_;
    bool behind_ = false;
    unsigned on_time_ = 0;
};

// Every tick of its timer, the cache marks the overdue devices stale, and each device going
// stale or fresh again is logged once.
class StalenessWatch {
public:
    StalenessWatch(EventLoop& loop, ValueCache& cache, std::chrono::milliseconds tick, GatewayLog log)
        : loop_(loop), timer_(loop), cache_(cache), tick_(tick), log_(std::move(log)) {
        arm();
    }

private:
    void arm() {
        // Cancelled when the watch goes (LoopTimer).
        timer_.set(loop_.clock()->now() + tick_, [this] {
            look();
            arm();
        });
    }

    void look() {
        const auto now_list = cache_.mark_overdue();
        const std::set<std::string> now(now_list.begin(), now_list.end());
        if (log_) {
            for (const auto& name : now) {
                if (stale_.count(name)) continue;
                log_(fmt::format("warning: device {} is stale: its poll is more than {} intervals overdue, so its values "
                                 "read \"stale\" until a poll reads them again",
                                 name, overdue_intervals_allowed));
            }
            for (const auto& name : stale_) {
                if (!now.count(name)) log_(fmt::format("notice: device {} is polled again: its values are current", name));
            }
        }
        stale_ = now;
    }

    EventLoop& loop_;
    LoopTimer timer_;
    ValueCache& cache_;
    std::chrono::milliseconds tick_;
    GatewayLog log_;
    std::set<std::string> stale_;
};

}  // namespace

std::chrono::milliseconds staleness_tick(std::chrono::milliseconds shortest_interval) {
    return std::clamp(shortest_interval / 4, std::chrono::milliseconds(50), std::chrono::milliseconds(1000));
}

// One poll group: its devices, and the sample in progress. Lives on the engine's loop thread.
struct PollGroups::Group {
    Group(EventLoop& loop, std::chrono::milliseconds every) : interval(every), timer(loop), schedule(loop.clock()->now(), every) {}

    std::chrono::milliseconds interval;
    std::vector<std::unique_ptr<ScheduledMaster>> masters;  // one per device: each names its line
    std::vector<std::unique_ptr<device::DeviceClient>> clients;
    std::vector<device::MonitorTarget> targets;
    std::vector<device::WatchedDevice> watched;
    std::vector<std::string> names;  // per device: its configured name
    // Per device: the words bounding its values, when they were last read, whether this poll reads them.
    std::vector<std::vector<const device::Parameter*>> bounds;
    std::vector<std::optional<device::MonitorClock::time_point>> limits_read_at;
    std::vector<bool> reading_limits;
    std::unique_ptr<CachingSink> sink;
    LoopTimer timer;  // cancelled when the group goes
    device::SampleSchedule schedule;
    unsigned index = 0;       // of the sample in progress, 1-based
    unsigned missed = 0;      // slots skipped before it
    std::size_t polling = 0;  // its devices still being read
    std::chrono::system_clock::time_point wall;  // when it started
};

// Every group's timers and polls, on the engine's loop (one thread for all of them), and the
// reads in flight on the lines' threads (each ends by posting its outcome into the loop).
struct PollGroups::State {
    explicit State(EventLoop& engine_loop) : loop(engine_loop) {}

    Instant now() const { return loop.clock()->now(); }

    void start_sample(Group& group) {
        if (stopping.stop_requested()) return;
        ++group.index;
        group.wall = loop.wall_now();
        group.polling = 0;
        for (std::size_t i = 0; i < group.clients.size(); ++i) {
            auto& watched = group.watched[i];
            watched.missed += group.missed;
            // The unit's back-off is the line's (line_scheduler.hpp): a unit backing off is skipped.
            if (const auto held = group.targets[i].held_until()) {
                device::record_skipped(watched);
                watched.next_try = held;
                continue;
            }
            ++group.polling;
            read_started();
            group.clients[i]->read_async(parameters_of(group, i), stopping.get_token(),
                                         [this, &group, i](device::ReadReport report, std::optional<Error> stopped_by) {
                                             loop.post([this, &group, i, report = std::move(report),
                                                        stopped_by = std::move(stopped_by)] {
                                                 if (!taken_down) device_polled(group, i, report, stopped_by);
                                             });
                                             read_ended();
                                         });
        }
        if (group.polling == 0) end_sample(group);
    }

    // The device's polled parameters, and the words bounding them when those are due again.
    std::vector<const device::Parameter*> parameters_of(Group& group, std::size_t i) const {
        auto parameters = device::with_identity_words(group.targets[i].parameters, group.watched[i]);
        const auto& read_at = group.limits_read_at[i];
        group.reading_limits[i] = !group.bounds[i].empty() && (!read_at || now() - *read_at >= limits_refresh);
        if (group.reading_limits[i]) parameters.insert(parameters.end(), group.bounds[i].begin(), group.bounds[i].end());
        return parameters;
    }

    void device_polled(Group& group, std::size_t i, const device::ReadReport& report, const std::optional<Error>& stopped_by) {
        if (group.reading_limits[i] && !stopped_by) group.limits_read_at[i] = now();
        device::record_outcome(group.watched[i], report, stopped_by, now());
        // Stamped here, on the loop that also marks devices stale: a `stale` found before this
        // reply was handled is stamped before it.
        group.sink->polled(i, loop.wall_now());
        if (--group.polling == 0) end_sample(group);
    }

    // Every device of the sample has been read (or skipped): the sample goes to the cache, and
    // the next one waits for its slot.
    void end_sample(Group& group) {
        const auto ended = now();
        group.sink->write(device::SampleView{group.index, group.wall, ended, &group.watched, group.missed});
        const auto next = group.schedule.after(ended);
        group.missed = next.missed;
        group.timer.set(next.at, [this, &group] { start_sample(group); });
    }

    void read_started() {
        std::lock_guard lock(reads_mutex);
        ++reads;
    }

    // On a line's thread, once the read's outcome is posted. Notified under the lock: the
    // destructor may go on as soon as it sees none left.
    void read_ended() {
        std::lock_guard lock(reads_mutex);
        --reads;
        no_reads.notify_all();
    }

    // No sample starts after this; the reads on the wire end (their next blocks unsent), and
    // once their outcomes have been handled the groups go, on the loop's thread.
    void stop() {
        stopping.request_stop();
        // A sample the loop was starting as the stop came may still be starting its reads: once
        // the loop has run this, every sample has either seen the stop or counted its reads.
        loop.take_down([] {});
        {
            std::unique_lock lock(reads_mutex);
            no_reads.wait(lock, [this] { return reads == 0; });
        }
        loop.take_down([this] {
            taken_down = true;  // an outcome posted after this finds no group to go to
            staleness.reset();
            groups.clear();
        });
    }

    EventLoop& loop;
    std::stop_source stopping;
    std::mutex reads_mutex;
    std::condition_variable no_reads;
    std::size_t reads = 0;
    std::vector<std::unique_ptr<Group>> groups;
    std::unique_ptr<StalenessWatch> staleness;
    bool taken_down = false;  // on the loop's thread only
};

PollGroups::PollGroups(EventLoop& loop, const GatewayConfig& config,
                       const std::map<std::string, std::shared_ptr<LineScheduler>>& lines, ValueCache& cache, GatewayLog log,
                       device::SampleSink* also)
    : state_(std::make_unique<State>(loop)) {
    State& state = *state_;
    // A group per line and interval: a sample ends when all its devices are read, so a group
    // spanning lines would hold a line's next polls until the slowest other line was done.
    using Key = std::pair<std::string, std::chrono::milliseconds>;
    std::map<Key, std::unique_ptr<Group>> by_interval;
    std::map<Key, std::vector<std::string>> names;
    std::chrono::milliseconds shortest = std::chrono::milliseconds::max();
    for (const auto& line : config.lines) {
        const auto& scheduler = lines.at(line.name);
        for (const auto& device : line.devices) {
            const Key key{line.name, device.poll};
            shortest = std::min(shortest, device.poll);
            auto& group = by_interval[key];
            if (!group) group = std::make_unique<Group>(state.loop, device.poll);
            // A poll waiting longer than its interval would only be stale when it came back.
            group->masters.push_back(
                std::make_unique<ScheduledMaster>(scheduler, line.link.to_string(), Priority::poll, device.poll, loop.clock()));
            group->clients.push_back(std::make_unique<device::DeviceClient>(*group->masters.back(), device.address));
            const std::uint8_t unit = device.address.unit;
            group->targets.push_back({group->masters.back().get(), device.address, polled_parameters(device),
                                      [scheduler, unit] { return scheduler->hold_poll(unit); }});
            group->watched.push_back(device::watch(fmt::format("{}@{}", device.address.profile->id, unit),
                                                   group->targets.back().parameters,
                                                   device.identify ? device.address.profile.get() : nullptr));
            group->bounds.push_back(bound_words(*device.address.profile, group->targets.back().parameters));
            group->names.push_back(device.name);
            group->limits_read_at.emplace_back();
            group->reading_limits.push_back(false);
            names[key].push_back(device.name);
            cache.expect_polls(device.name, device.poll);
        }
    }
    for (auto& [key, group] : by_interval) {
        group->sink = std::make_unique<CachingSink>(key.second, std::move(names[key]), std::vector<std::string>{key.first}, cache,
                                                    log, also);
        state.groups.push_back(std::move(group));
    }
    if (by_interval.empty()) return;
    // Started on the loop's thread, which alone touches the groups and their timers from now on.
    const auto tick = staleness_tick(shortest);
    loop.post([&state, &cache, tick, log = std::move(log)] {
        state.staleness = std::make_unique<StalenessWatch>(state.loop, cache, tick, log);
        for (auto& group : state.groups) state.start_sample(*group);
    });
    size_ = state.groups.size();
}

PollGroups::~PollGroups() { state_->stop(); }

void PollGroups::written(const std::string& device, const std::vector<std::string>& parameters) {
    refresh_limits_of(device, [&](const device::Parameter& bound) {
        return std::find(parameters.begin(), parameters.end(), bound.name) != parameters.end();
    });
}

void PollGroups::written_unknown(const std::string& device) {
    refresh_limits_of(device, [](const device::Parameter&) { return true; });
}

void PollGroups::refresh_limits_of(const std::string& device, const std::function<bool(const device::Parameter&)>& moved) {
    for (auto& group : state_->groups) {
        for (std::size_t i = 0; i < group->names.size(); ++i) {
            if (group->names[i] != device) continue;
            const auto& bounds = group->bounds[i];
            if (std::any_of(bounds.begin(), bounds.end(), [&](const device::Parameter* bound) { return moved(*bound); })) {
                group->limits_read_at[i].reset();
            }
        }
    }
}

}  // namespace loopwire::gateway
