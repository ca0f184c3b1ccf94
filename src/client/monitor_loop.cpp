#include "client/monitor_loop.hpp"

#include <condition_variable>
#include <cstdint>
#include <mutex>

#include <fmt/format.h>

#include "client/monitor_backoff.hpp"

namespace loopwire::device {
namespace {

// Passes requests to the shared master until one times out or the link fails; after that, every
// further request of the same poll fails at once with that error instead of waiting again. A
// DeviceClient read spanning several blocks thus spends one timeout on a dead unit, not one per
// block.
class StopAtFirstTimeout final : public session::Master {
public:
    explicit StopAtFirstTimeout(session::Master& inner) : inner_(inner) {}

    Result<codec::Reply> execute(std::uint8_t unit, const codec::Request& request) override {
        if (failure_) return *failure_;
        auto reply = inner_.execute(unit, request);
        if (!reply && (reply.error().kind == ErrorKind::timeout || reply.error().kind == ErrorKind::link)) failure_ = reply.error();
        return reply;
    }
    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override {
        inner_.execute_async(unit, std::move(request), std::move(done));
    }
    Result<Bytes> forward(std::uint8_t unit, ByteView pdu) override { return inner_.forward(unit, pdu); }
    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override {
        inner_.forward_async(unit, std::move(pdu), std::move(done));
    }
    std::string describe() const override { return inner_.describe(); }

    void start_poll() { failure_.reset(); }
    const std::optional<Error>& failure() const { return failure_; }

private:
    session::Master& inner_;
    std::optional<Error> failure_;
};

struct Polled {
    std::unique_ptr<StopAtFirstTimeout> guard;
    std::unique_ptr<device::DeviceClient> client;
    const MonitorTarget* target;
    RetryBackoff backoff;
};

std::string label_of(const device::DeviceAddress& device) { return fmt::format("{}@{}", device.profile->id, device.unit); }

// When the device's next poll may go, if not now: the carrier's word when it keeps the
// back-off (MonitorTarget::held_until), else the poller's own.
std::optional<MonitorClock::time_point> held_until(const Polled& polled, MonitorClock::time_point sample_start) {
    if (polled.target->held_until) return polled.target->held_until();
    if (polled.backoff.due(sample_start)) return std::nullopt;
    return polled.backoff.next_try();
}

void poll(Polled& polled, WatchedDevice& watched, MonitorClock::time_point sample_start) {
    const bool own_backoff = !polled.target->held_until;
    if (const auto held = held_until(polled, sample_start)) {
        record_skipped(watched);
        watched.next_try = held;
        return;
    }
    polled.guard->start_poll();
    const auto report = polled.client->read(with_identity_words(polled.target->parameters, watched));
    const auto now = MonitorClock::now();
    const auto& failure = polled.guard->failure();
    record_outcome(watched, report, failure, now);
    if (!failure) {
        polled.backoff.succeeded();
    } else if (own_backoff) {
        polled.backoff.failed(now);
        watched.next_try = polled.backoff.next_try();
    }
}

// Sleeps until `deadline` or until stop is requested; false when stopped.
bool sleep_until(MonitorClock::time_point deadline, std::stop_token stop) {
    std::mutex mutex;
    std::condition_variable_any woken;
    std::unique_lock lock(mutex);
    woken.wait_until(lock, stop, deadline, [] { return false; });
    return !stop.stop_requested();
}

}  // namespace

SampleSchedule::Next SampleSchedule::after(MonitorClock::time_point now) {
    // The next slot of the fixed schedule that is still ahead.
    const std::int64_t next = (now - start_) / interval_ + 1;
    const unsigned missed = next > slot_ + 1 ? static_cast<unsigned>(next - slot_ - 1) : 0u;
    slot_ = next;
    return {start_ + next * interval_, missed};
}

void run_monitor(const std::vector<MonitorTarget>& targets, const MonitorSettings& settings, SampleSink& sink,
                 std::stop_token stop) {
    std::vector<Polled> polled;
    std::vector<WatchedDevice> watched;
    for (const auto& target : targets) {
        auto guard = std::make_unique<StopAtFirstTimeout>(*target.master);
        auto client = std::make_unique<device::DeviceClient>(*guard, target.device);
        polled.push_back(Polled{std::move(guard), std::move(client), &target, RetryBackoff(settings.interval, settings.backoff_cap)});
        watched.push_back(watch(label_of(target.device), target.parameters, target.identify ? target.device.profile.get() : nullptr));
    }
    SampleSteps steps;
    steps.poll = [&](unsigned missed) {
        const auto sample_start = MonitorClock::now();
        for (std::size_t i = 0; i < polled.size() && !stop.stop_requested(); ++i) {
            watched[i].missed += missed;
            poll(polled[i], watched[i], sample_start);
        }
    };
    steps.write = [&](unsigned index, std::chrono::system_clock::time_point time, unsigned missed) {
        sink.write(SampleView{index, time, MonitorClock::now(), &watched, missed});
    };
    run_sample_schedule(settings, steps, stop);
}

void run_sample_schedule(const MonitorSettings& settings, const SampleSteps& steps, const std::stop_token& stop) {
    SampleSchedule schedule(MonitorClock::now(), settings.interval);
    unsigned missed = 0;  // slots skipped before the sample about to start
    for (unsigned index = 1; !stop.stop_requested() && (!settings.count || index <= *settings.count); ++index) {
        const auto wall = std::chrono::system_clock::now();
        steps.poll(missed);
        if (stop.stop_requested()) break;
        steps.write(index, wall, missed);
        if (settings.count && index == *settings.count) break;
        const auto next = schedule.after(MonitorClock::now());
        missed = next.missed;
        if (!sleep_until(next.at, stop)) break;
    }
}

}  // namespace loopwire::device
