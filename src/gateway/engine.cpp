#include "gateway/engine.hpp"

#include <future>

#include <boost/asio/post.hpp>

#include "common/thread_name.hpp"
#include "session/write_batching.hpp"

namespace loopwire::gateway {

Engine::Engine()
    : own_loop_(std::make_unique<boost::asio::io_context>()),
      loop_(*own_loop_),
      busy_(boost::asio::make_work_guard(loop_)),
      thread_([this] {
          // What the loop's handlers send to a pipelined Modbus TCP line in one round (a poll
          // sample's devices, writes by name) goes to the device in one write, as the Modbus TCP
          // front's requests do (session/write_batching.hpp).
          session::WriteBatching::Scope batching([this](std::function<void()> work) { boost::asio::post(loop_, std::move(work)); });
          loop_.run();
      }) {
    name_thread(thread_.native_handle(), "lw-engine");
}

// The loop's owner runs it and batches its handlers' writes (gateway/modbus_tcp_front.cpp: the
// TCP slave holds a WriteBatching::Scope on its thread). The thread is named for what it now
// carries, so that `top -H` shows the polls' time where it is spent.
Engine::Engine(boost::asio::io_context& shared) : loop_(shared), busy_(boost::asio::make_work_guard(loop_)) {
    boost::asio::post(loop_, [] { name_thread(pthread_self(), "lw-engine"); });
}

Engine::~Engine() { stop(); }

void Engine::post(std::function<void()> work) { boost::asio::post(loop_, std::move(work)); }

EventLoop::TimerId Engine::at(Instant when, std::function<void()> work) {
    const TimerId id = next_timer_++;
    auto& timer = timers_->try_emplace(id, loop_).first->second;
    timer.expires_at(when);
    timer.async_wait([timers = std::weak_ptr<Timers>(timers_), id, work = std::move(work)](const boost::system::error_code& error) {
        const auto table = timers.lock();
        // Cancelled (the wait aborted, or due already and then taken out of the table).
        if (error || !table || table->erase(id) == 0) return;
        work();
    });
    return id;
}

void Engine::cancel(TimerId id) { timers_->erase(id); }

void Engine::take_down(const std::function<void()>& work) {
    if (loop_.stopped() || (own_loop_ && !thread_.joinable())) return work();
    std::promise<void> ran;
    auto done = ran.get_future();
    boost::asio::post(loop_, [&work, &ran] {
        work();
        ran.set_value();
    });
    done.wait();
}

void Engine::stop() {
    busy_.reset();
    if (!own_loop_) return;
    loop_.stop();
    if (thread_.joinable()) thread_.join();
}

}  // namespace loopwire::gateway
