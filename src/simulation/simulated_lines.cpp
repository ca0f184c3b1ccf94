#include "simulation/simulated_lines.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <deque>
#include <future>
#include <mutex>
#include <optional>
#include <vector>

namespace loopwire::simulation {
namespace {

struct ServedLine {
    ServedLine(std::unique_ptr<transport::ByteStream> stream, std::unique_ptr<session::Slave> served)
        : port(std::move(stream)), devices(std::move(served)), steps(*devices) {}

    std::unique_ptr<transport::ByteStream> port;
    std::unique_ptr<session::Slave> devices;
    session::Slave::StreamSteps steps;
    std::deque<session::Slave::TimedReply> replies;  // in the order they were called for
    bool failed = false;
    std::optional<session::LineLoop::WaitId> waiting;  // the port's wait on the loop

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

    // Reads everything the port has now (at `now`).
    void read_available(const Clock& clock) {
        std::array<std::uint8_t, 1024> buffer{};
        while (!failed) {
            auto got = port->read_some(buffer, std::chrono::milliseconds::zero());
            if (!got) {
                failed = true;
                return;
            }
            if (*got == 0) return;
            heard(ByteView(buffer.data(), *got), clock.now());
        }
    }
};

}  // namespace

struct SimulatedLines::State {
    explicit State(std::shared_ptr<session::LineLoop> lines_loop) : loop(std::move(lines_loop)) {}

    // On the loop: serves `line` whenever its port has bytes or its next deadline comes. Each
    // wake reads what the port has before it looks at the silences: a frame's bytes read late
    // (the loop busy with another line) must reach the framing before it takes the time since
    // its last bytes for a silence that ends the frame (codec/rtu.hpp: a silence the reader
    // observes itself is never second-guessed), as Slave::serve_stream flushes only after a
    // read that found nothing.
    void watch(ServedLine* line) {
        const int handle = line->port->poll_handle();
        line->waiting = loop->wait(handle, line->next_due().value_or(Instant::max()), [this, line] {
            line->waiting.reset();
            line->read_available(*loop->clock());
            if (!line->failed) line->serve_due(loop->clock()->now());
            if (line->failed) {
                failed.fetch_add(1, std::memory_order_relaxed);
                return;
            }
            watch(line);
        });
    }

    // From the destructor: once this has returned, no wait on the loop refers to a line.
    void leave_loop() {
        std::promise<void> left;
        loop->post([this, &left] {
            {
                std::lock_guard lock(mutex);
                for (const auto& line : lines) {
                    if (line->waiting) loop->cancel(*line->waiting);
                }
            }
            left.set_value();
        });
        left.get_future().wait();
    }

    const std::shared_ptr<session::LineLoop> loop;
    mutable std::mutex mutex;  // guards `lines`, appended from any thread
    std::vector<std::unique_ptr<ServedLine>> lines;  // each served on the loop alone
    std::atomic<std::size_t> failed{0};
};

SimulatedLines::SimulatedLines(std::shared_ptr<session::LineLoop> loop) : state_(std::make_unique<State>(std::move(loop))) {}

SimulatedLines::~SimulatedLines() { state_->leave_loop(); }

Result<void> SimulatedLines::add(std::unique_ptr<transport::ByteStream> port, std::unique_ptr<session::Slave> devices) {
    if (port->poll_handle() < 0) {
        return make_error(ErrorKind::usage, port->describe() + " has no handle to wait on with the other simulated lines");
    }
    ServedLine* added = nullptr;
    {
        std::lock_guard lock(state_->mutex);
        state_->lines.push_back(std::make_unique<ServedLine>(std::move(port), std::move(devices)));
        added = state_->lines.back().get();
    }
    state_->loop->post([s = state_.get(), added] { s->watch(added); });
    return {};
}

std::size_t SimulatedLines::lines() const {
    std::lock_guard lock(state_->mutex);
    return state_->lines.size();
}

std::size_t SimulatedLines::failed() const { return state_->failed.load(std::memory_order_relaxed); }

}  // namespace loopwire::simulation
