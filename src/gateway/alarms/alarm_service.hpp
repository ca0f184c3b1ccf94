#pragma once
// The gateway's alarms at work: an AlarmEngine (alarm_engine.hpp) fed every change the value
// cache tells (the polls' resolved values and each device's status), ticked every second on the
// engine's loop for delays and shelving that end, its transitions logged, journaled
// (alarm_journal.hpp) and told to whoever listens (MQTT). The fronts (HTTP, /metrics) read its
// views and act on it from any thread: one lock around the engine, held for microseconds.
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "gateway/alarms/alarm_engine.hpp"
#include "gateway/alarms/alarm_journal.hpp"
#include "gateway/event_loop.hpp"
#include "gateway/value_cache.hpp"

namespace loopwire::gateway::alarms {

enum class AlarmAction { acknowledge, shelve, unshelve, remove_from_service, return_to_service };

class AlarmService final {
public:
    using Log = std::function<void(const std::string&)>;
    // `journal`: none without [history] (the states then start normal at every start); else it
    // outlives the service, and is written by its owner (AlarmJournal: the history's writer).
    AlarmService(EventLoop& loop, ValueCache& cache, std::vector<LimitAlarm> limits, const std::vector<std::string>& devices,
                 AlarmJournal* journal, std::filesystem::path database, Log log);
    ~AlarmService();  // taken down from the loop first
    AlarmService(const AlarmService&) = delete;
    AlarmService& operator=(const AlarmService&) = delete;

    std::vector<AlarmView> views() const;
    AlarmEngine::Outcome act(AlarmAction action, const std::string& id, const std::string& user, const std::string& comment,
                             std::chrono::milliseconds duration = {});
    // Each transition, as it happens (on the thread that made it); set before values flow.
    void on_transition(std::function<void(const AlarmTransition&)> listener);

    // The history file the journal is in; empty without [history].
    const std::filesystem::path& database() const { return database_; }

private:
    void take(const Transitions& transitions);  // under the lock
    void arm();

    EventLoop& loop_;
    Log log_;
    std::filesystem::path database_;
    mutable std::mutex mutex_;
    AlarmEngine engine_;
    AlarmJournal* journal_ = nullptr;
    std::function<void(const AlarmTransition&)> listener_;
    std::optional<LoopTimer> timer_;  // the loop's only
    ValueSubscription subscription_;  // last: ends before the rest goes
};

// /metrics' lines: loopwire_alarm_active{device,alarm,severity} 0 or 1, and the alarms in each state.
std::string alarm_metrics(const std::vector<AlarmView>& views);

}  // namespace loopwire::gateway::alarms
