#include "gateway/alarms/alarm_service.hpp"

#include <map>

#include <fmt/format.h>

namespace loopwire::gateway::alarms {
namespace {

constexpr std::chrono::seconds tick_interval{1};

std::optional<double> number_of(const ValueChange& change) {
    if (!change.value) return std::nullopt;
    if (const auto* number = std::get_if<double>(&change.value->value)) return *number;
    return std::nullopt;
}

std::string log_line(const AlarmTransition& transition) {
    std::string line = fmt::format("alarm {}: {} ({}", transition.id, name_of(transition.state), transition.message);
    if (transition.value) line += fmt::format("; {}{}{}", *transition.value, transition.unit.empty() ? "" : " ", transition.unit);
    line += ")";
    if (!transition.user.empty()) line += fmt::format(" by {}", transition.user);
    if (!transition.comment.empty()) line += fmt::format(": {}", transition.comment);
    return line;
}

}  // namespace

AlarmService::AlarmService(EventLoop& loop, ValueCache& cache, std::vector<LimitAlarm> limits,
                           const std::vector<std::string>& devices, AlarmJournal* journal,
                           std::filesystem::path database, Log log)
    : loop_(loop), log_(std::move(log)), database_(std::move(database)), engine_(std::move(limits), devices),
      journal_(journal) {
    if (journal_) engine_.restore(journal_->last_states());
    subscription_ = cache.subscribe([this](const ValueChange& change) {
        std::lock_guard lock(mutex_);
        if (change.about_device()) {
            take(engine_.feed_device(change.device, change.device_status, change.sampled));
        } else {
            take(engine_.feed(change.device, change.parameter, number_of(change), change.status, change.unit, change.sampled));
        }
    });
    loop_.post([this] {
        timer_.emplace(loop_);
        arm();
    });
}

AlarmService::~AlarmService() {
    subscription_.reset();
    loop_.take_down([this] { timer_.reset(); });
}

void AlarmService::arm() {
    timer_->set(loop_.clock()->now() + tick_interval, [this] {
        {
            std::lock_guard lock(mutex_);
            take(engine_.tick(loop_.wall_now()));
        }
        arm();
    });
}

void AlarmService::take(const Transitions& transitions) {
    if (transitions.empty()) return;
    for (const AlarmTransition& transition : transitions) {
        if (log_) log_(log_line(transition));
        if (listener_) listener_(transition);
    }
    if (journal_) journal_->append(transitions);
}

std::vector<AlarmView> AlarmService::views() const {
    std::lock_guard lock(mutex_);
    return engine_.views();
}

AlarmEngine::Outcome AlarmService::act(AlarmAction action, const std::string& id, const std::string& user,
                                       const std::string& comment, std::chrono::milliseconds duration) {
    std::lock_guard lock(mutex_);
    const auto now = loop_.wall_now();
    AlarmEngine::Outcome outcome;
    switch (action) {
        case AlarmAction::acknowledge: outcome = engine_.acknowledge(id, user, comment, now); break;
        case AlarmAction::shelve: outcome = engine_.shelve(id, duration, user, comment, now); break;
        case AlarmAction::unshelve: outcome = engine_.unshelve(id, user, comment, now); break;
        case AlarmAction::remove_from_service: outcome = engine_.remove_from_service(id, user, comment, now); break;
        case AlarmAction::return_to_service: outcome = engine_.return_to_service(id, user, comment, now); break;
    }
    take(outcome.transitions);
    return outcome;
}

void AlarmService::on_transition(std::function<void(const AlarmTransition&)> listener) {
    std::lock_guard lock(mutex_);
    listener_ = std::move(listener);
}

std::string alarm_metrics(const std::vector<AlarmView>& views) {
    if (views.empty()) return {};
    std::string out =
        "# HELP loopwire_alarm_active Whether the alarm is active (active-unacknowledged or active-acknowledged).\n"
        "# TYPE loopwire_alarm_active gauge\n";
    std::map<std::string_view, int> by_state;
    for (const auto state : {AlarmState::normal, AlarmState::active_unacknowledged, AlarmState::active_acknowledged,
                             AlarmState::returned_unacknowledged, AlarmState::shelved, AlarmState::out_of_service}) {
        by_state[name_of(state)] = 0;
    }
    for (const AlarmView& view : views) {
        out += fmt::format("loopwire_alarm_active{{device=\"{}\",alarm=\"{}\",severity=\"{}\"}} {}\n", view.device, view.name,
                           name_of(view.severity), is_active(view.state) ? 1 : 0);
        ++by_state[name_of(view.state)];
    }
    out += "# HELP loopwire_alarms The alarms in each state.\n# TYPE loopwire_alarms gauge\n";
    for (const auto& [state, count] : by_state) out += fmt::format("loopwire_alarms{{state=\"{}\"}} {}\n", state, count);
    return out;
}

}  // namespace loopwire::gateway::alarms
