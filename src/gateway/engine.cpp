#include "gateway/engine.hpp"

#include <future>

#include <boost/asio/post.hpp>

namespace loopwire::gateway {

Engine::Engine() : busy_(boost::asio::make_work_guard(loop_)), thread_([this] { loop_.run(); }) {}

Engine::~Engine() { stop(); }

void Engine::take_down(const std::function<void()>& work) {
    if (loop_.stopped() || !thread_.joinable()) return work();
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
    loop_.stop();
    if (thread_.joinable()) thread_.join();
}

}  // namespace loopwire::gateway
