#include "gateway/event_loop.hpp"

#include <future>
#include <utility>

#include "session/line_loop.hpp"

namespace loopwire::gateway {

void LoopTimer::set(Instant when, std::function<void()> work) {
    cancel();
    id_ = loop_.at(when, [this, work = std::move(work)] {
        id_.reset();  // run: nothing left to cancel
        work();
    });
}

void LoopTimer::cancel() {
    if (id_) loop_.cancel(*std::exchange(id_, std::nullopt));
}

LineLoopEvents::LineLoopEvents(std::shared_ptr<session::LineLoop> loop)
    : loop_(std::move(loop)), started_(loop_->clock()->now()), wall_started_(std::chrono::system_clock::now()) {}

void LineLoopEvents::post(std::function<void()> work) { loop_->post(std::move(work)); }

EventLoop::TimerId LineLoopEvents::at(Instant when, std::function<void()> work) { return loop_->wait(-1, when, std::move(work)); }

void LineLoopEvents::cancel(TimerId id) { loop_->cancel(id); }

const std::shared_ptr<Clock>& LineLoopEvents::clock() const { return loop_->clock(); }

std::chrono::system_clock::time_point LineLoopEvents::wall_now() const {
    return wall_started_ + std::chrono::duration_cast<std::chrono::system_clock::duration>(clock()->now() - started_);
}

void LineLoopEvents::take_down(const std::function<void()>& work) {
    std::promise<void> ran;
    auto done = ran.get_future();
    loop_->post([&work, &ran] {
        work();
        ran.set_value();
    });
    done.wait();
}

}  // namespace loopwire::gateway
