#include "simulation/simulated_lines.hpp"

#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <deque>
#include <mutex>
#include <thread>
#include <vector>

#include "common/thread_name.hpp"

namespace loopwire::simulation {
namespace {

using std::chrono::steady_clock;

// The longest wait without a reason to wake: bounds how late a stop is noticed if the wake-up
// write were ever lost.
constexpr auto longest_wait = std::chrono::milliseconds(100);

struct ServedLine {
    ServedLine(std::unique_ptr<transport::ByteStream> stream, std::unique_ptr<session::Slave> served)
        : port(std::move(stream)), devices(std::move(served)), steps(*devices) {}

    std::unique_ptr<transport::ByteStream> port;
    std::unique_ptr<session::Slave> devices;
    session::Slave::StreamSteps steps;
    std::deque<session::Slave::TimedReply> replies;  // in the order they were called for
    bool failed = false;

    // What `bytes` (empty: the silence until `now`) call for, queued to go at their times.
    void heard(ByteView bytes, Instant now) {
        auto replies_now = steps.heard(bytes, now);
        if (!replies_now) {
            failed = true;
            return;
        }
        for (auto& reply : *replies_now) replies.push_back(std::move(reply));
        if (steps.broken()) failed = true;  // after answering what came before
    }

    // Sends the replies that are due and flushes a frame whose silence has passed.
    void serve_due(Instant now) {
        while (!replies.empty() && replies.front().not_before <= now) {
            steps.sending(replies.front());
            if (!port->write(replies.front().frame)) failed = true;
            replies.pop_front();
        }
        if (auto flush_at = steps.flush_deadline(); flush_at && *flush_at <= now) heard({}, now);
    }

    // The next time serve_due() has something to do, if any.
    std::optional<Instant> next_due() const {
        std::optional<Instant> next = steps.flush_deadline();
        if (!replies.empty() && (!next || replies.front().not_before < *next)) next = replies.front().not_before;
        return next;
    }

    // Reads everything the port has now.
    void read_available() {
        std::array<std::uint8_t, 1024> buffer{};
        while (!failed) {
            auto got = port->read_some(buffer, std::chrono::milliseconds::zero());
            if (!got) {
                failed = true;
                return;
            }
            if (*got == 0) return;
            heard(ByteView(buffer.data(), *got), steady_clock::now());
        }
    }
};

}  // namespace

struct SimulatedLines::State {
    State() : wake(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {}
    ~State() {
        if (wake >= 0) ::close(wake);
    }

    void notify() const {
        const std::uint64_t one = 1;
        (void)!::write(wake, &one, sizeof one);
    }

    std::vector<ServedLine*> snapshot() {
        std::lock_guard lock(mutex);
        std::vector<ServedLine*> served;
        for (const auto& line : lines) served.push_back(line.get());
        return served;
    }

    void run(const std::stop_token& stop);
    void wait(const std::vector<ServedLine*>& served, Instant now);

    const int wake;  // eventfd: a line added, or stop
    mutable std::mutex mutex;
    std::vector<std::unique_ptr<ServedLine>> lines;  // appended only; served by the thread alone
    std::atomic<std::size_t> failed{0};
    std::jthread thread;  // last: stops before the lines go
};

// Each round reads what every port has before it looks at the silences: a frame's bytes read
// late (the thread scheduled late, or busy with another line) must reach the framing before it
// takes the time since its last bytes for a silence that ends the frame (codec/rtu.hpp: a
// silence the reader observes itself is never second-guessed), as Slave::serve_stream flushes
// only after a read that found nothing.
void SimulatedLines::State::run(const std::stop_token& stop) {
    std::stop_callback wake_on_stop(stop, [this] { notify(); });
    while (!stop.stop_requested()) {
        const auto served = snapshot();
        for (ServedLine* line : served) {
            if (line->failed) continue;
            line->read_available();
            if (!line->failed) line->serve_due(steady_clock::now());
            if (line->failed) failed.fetch_add(1, std::memory_order_relaxed);
        }
        wait(served, steady_clock::now());
    }
}

// Until a port has bytes, a line has something due, a line is added or stop is asked.
void SimulatedLines::State::wait(const std::vector<ServedLine*>& served, Instant now) {
    Instant until = now + longest_wait;
    std::vector<pollfd> waited{{wake, POLLIN, 0}};
    for (const ServedLine* line : served) {
        if (line->failed) continue;
        if (auto next = line->next_due()) until = std::min(until, *next);
        waited.push_back({line->port->poll_handle(), POLLIN, 0});
    }
    const auto left = std::max(until - steady_clock::now(), Instant::duration::zero());
    const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(left).count();
    const timespec timeout{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
    (void)::ppoll(waited.data(), waited.size(), &timeout, nullptr);
    if ((waited[0].revents & POLLIN) != 0) {
        std::uint64_t count = 0;
        (void)!::read(wake, &count, sizeof count);
    }
}

SimulatedLines::SimulatedLines() : state_(std::make_unique<State>()) {
    state_->thread = std::jthread([s = state_.get()](const std::stop_token& stop) { s->run(stop); });
    name_thread(state_->thread.native_handle(), "lw-simulation");  // common/thread_name.hpp
}

SimulatedLines::~SimulatedLines() { state_->thread = std::jthread(); }

Result<void> SimulatedLines::add(std::unique_ptr<transport::ByteStream> port, std::unique_ptr<session::Slave> devices) {
    if (port->poll_handle() < 0) {
        return make_error(ErrorKind::usage, port->describe() + " has no handle to wait on with the other simulated lines");
    }
    {
        std::lock_guard lock(state_->mutex);
        state_->lines.push_back(std::make_unique<ServedLine>(std::move(port), std::move(devices)));
    }
    state_->notify();
    return {};
}

std::size_t SimulatedLines::lines() const {
    std::lock_guard lock(state_->mutex);
    return state_->lines.size();
}

std::size_t SimulatedLines::failed() const { return state_->failed.load(std::memory_order_relaxed); }

}  // namespace loopwire::simulation
