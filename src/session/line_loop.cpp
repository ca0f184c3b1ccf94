#include "session/line_loop.hpp"

#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "common/thread_name.hpp"

namespace loopwire::session {

struct LineLoop::State {
    struct Wait {
        int fd;
        Instant deadline;
        std::function<void()> wake;
    };

    State(std::shared_ptr<Clock> time, std::shared_ptr<VirtualClock> virtual_time)
        : clock(std::move(time)), virtual_clock(std::move(virtual_time)), wakeup(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {
        if (wakeup < 0) {
            std::perror("loopwire: eventfd for the lines' loop");
            std::abort();
        }
        thread = std::thread([this] { run(); });
        name_thread(thread.native_handle(), "lw-lines");
    }

    ~State() {
        {
            std::lock_guard lock(mutex);
            stopping = true;
        }
        signal();
        if (thread.joinable()) thread.join();
        ::close(wakeup);
    }

    void signal() const {
        const std::uint64_t one = 1;
        // A full counter already wakes the loop; nothing else can fail on an eventfd.
        [[maybe_unused]] const auto written = ::write(wakeup, &one, sizeof one);
    }

    void run() {
        for (;;) {
            if (!run_posted()) return;
            wake_due(clock->now());
            sleep_until_something();
        }
    }

    // False once stopping.
    bool run_posted() {
        std::deque<std::function<void()>> jobs;
        {
            std::lock_guard lock(mutex);
            if (stopping) return false;
            jobs.swap(posted);
        }
        for (auto& job : jobs) job();
        return true;
    }

    void wake_due(Instant now) {
        std::vector<WaitId> due;
        for (const auto& [id, wait] : waits) {
            if (wait.deadline <= now) due.push_back(id);
        }
        for (const auto id : due) wake(id);
    }

    // Takes the wait out before it runs: `wake` may wait again, or cancel others.
    void wake(WaitId id) {
        auto found = waits.find(id);
        if (found == waits.end()) return;
        auto callback = std::move(found->second.wake);
        waits.erase(found);
        callback();
    }

    void sleep_until_something() {
        std::vector<pollfd> watched{{wakeup, POLLIN, 0}};
        std::vector<WaitId> owners{0};
        Instant earliest = Instant::max();
        for (const auto& [id, wait] : waits) {
            earliest = std::min(earliest, wait.deadline);
            if (wait.fd < 0) continue;
            watched.push_back({wait.fd, POLLIN, 0});
            owners.push_back(id);
        }
        timespec timeout{};
        const timespec* limit = nullptr;
        if (virtual_clock) {
            // A look, not a sleep: time is moved below. With no deadline, or the time held: until
            // something is posted or ready.
            if (earliest != Instant::max() && holds.load() == 0) limit = &timeout;
        } else if (earliest != Instant::max()) {
            const auto left = std::max(earliest - clock->now(), Instant::duration::zero());
            const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(left);
            timeout.tv_sec = static_cast<time_t>(seconds.count());
            timeout.tv_nsec = static_cast<long>(std::chrono::duration_cast<std::chrono::nanoseconds>(left - seconds).count());
            limit = &timeout;
        }
        const int ready = ::ppoll(watched.data(), watched.size(), limit, nullptr);
        if (ready < 0) {
            if (errno == EINTR) return;
            std::perror("loopwire: ppoll in the lines' loop");
            std::abort();
        }
        if (watched[0].revents != 0) {
            std::uint64_t count = 0;
            [[maybe_unused]] const auto drained = ::read(wakeup, &count, sizeof count);
        }
        for (std::size_t i = 1; i < watched.size(); ++i) {
            if (watched[i].revents != 0) wake(owners[i]);
        }
        if (virtual_clock && ready == 0 && earliest != Instant::max() && holds.load() == 0 && nothing_posted()) {
            virtual_clock->sleep_until(earliest);
        }
    }

    bool nothing_posted() const {
        std::lock_guard lock(mutex);
        return posted.empty();
    }

    const std::shared_ptr<Clock> clock;
    const std::shared_ptr<VirtualClock> virtual_clock;  // null in steady time
    const int wakeup;
    std::atomic<int> holds{0};  // LineLoop::hold_time()
    mutable std::mutex mutex;  // guards `posted` and `stopping`
    std::deque<std::function<void()>> posted;
    bool stopping = false;
    std::map<WaitId, Wait> waits;  // the loop's thread only
    WaitId next_id = 1;
    std::thread thread;  // last: started once the rest exists
};

LineLoop::LineLoop() : state_(std::make_unique<State>(steady_clock(), nullptr)) {}

LineLoop::LineLoop(std::shared_ptr<VirtualClock> clock) : state_(std::make_unique<State>(clock, clock)) {}

LineLoop::~LineLoop() {
    if (on_loop_thread()) {
        // Destroyed by its own thread (the last owner let go in a job): it cannot join itself.
        std::fputs("loopwire: the lines' loop was destroyed on its own thread\n", stderr);
        std::abort();
    }
}

void LineLoop::post(std::function<void()> job) {
    {
        std::lock_guard lock(state_->mutex);
        state_->posted.push_back(std::move(job));
    }
    state_->signal();
}

bool LineLoop::on_loop_thread() const { return std::this_thread::get_id() == state_->thread.get_id(); }

const std::shared_ptr<Clock>& LineLoop::clock() const { return state_->clock; }

std::shared_ptr<void> LineLoop::hold_time() {
    if (!state_->virtual_clock) return nullptr;
    struct Hold {
        explicit Hold(State& held) : state(held) { ++state.holds; }
        ~Hold() {
            --state.holds;
            state.signal();  // the loop may move the time again
        }
        State& state;
    };
    return std::make_shared<Hold>(*state_);
}

LineLoop::WaitId LineLoop::wait(int fd, Instant deadline, std::function<void()> wake) {
    const WaitId id = state_->next_id++;
    state_->waits.emplace(id, State::Wait{fd, deadline, std::move(wake)});
    return id;
}

void LineLoop::cancel(WaitId id) { state_->waits.erase(id); }

}  // namespace loopwire::session
