#pragma once
// The gateway's event loop: one thread that runs the polls (their timers and the outcomes of
// their reads, gateway/poll_groups.hpp), the writes by name from MQTT and HTTP
// (gateway/device_writer.hpp) and the statistics timer, however many lines, devices and poll
// intervals there are. What runs on it must not block: requests go to the lines' schedulers
// asynchronously and their completions are posted back into the loop. Frames its handlers send
// to a pipelined Modbus TCP line in one round go out in one write (session/write_batching.hpp).
//
// Lifetime: whatever posts work or holds timers on the loop is taken down with take_down()
// before it goes, and the engine outlives all of them.
//
// On a shared loop (the kept Modbus TCP front's, gateway/modbus_tcp_front.hpp) the engine has
// no thread: the loop's owner runs it, and keeps running it for as long as the engine exists;
// stop() then only ends the engine's own part (nothing is dropped from a loop it does not own,
// which is why every part takes itself down first).
#include <functional>
#include <map>
#include <memory>
#include <thread>

#include <boost/asio/io_context.hpp>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/steady_timer.hpp>

#include "gateway/event_loop.hpp"

namespace loopwire::gateway {

// Its timers (EventLoop) are Asio's on the steady clock; samples are stamped with the system clock.
class Engine final : public EventLoop {
public:
    Engine();   // the loop runs from here on, on a thread named lw-engine
    explicit Engine(boost::asio::io_context& shared);
    ~Engine() override;  // stop()
    Engine(const Engine&) = delete;
    Engine& operator=(const Engine&) = delete;

    boost::asio::io_context& loop() { return loop_; }

    void post(std::function<void()> work) override;
    TimerId at(Instant when, std::function<void()> work) override;
    void cancel(TimerId id) override;
    const std::shared_ptr<Clock>& clock() const override { return clock_; }
    std::chrono::system_clock::time_point wall_now() const override { return std::chrono::system_clock::now(); }
    // Runs `work` on the loop's thread after everything posted before it, and returns once it
    // has run: what a part does to take itself down (cancel its timers, drop its state) while
    // the loop goes on for the others. Runs `work` here when the loop has stopped. Never call
    // it from the loop's own thread.
    void take_down(const std::function<void()>& work) override;

    // Ends the loop (handlers not yet run are dropped) and joins its thread. Idempotent.
    void stop();

private:
    std::unique_ptr<boost::asio::io_context> own_loop_;  // none on a shared loop
    boost::asio::io_context& loop_;
    boost::asio::executor_work_guard<boost::asio::io_context::executor_type> busy_;
    // The timers set, by id; on the loop's thread only. Gone before the loop they wait on, and
    // shared with their waits, which may outlive the engine on a shared loop (a wait already due
    // when cancelled still runs).
    using Timers = std::map<TimerId, boost::asio::steady_timer>;
    std::shared_ptr<Clock> clock_ = steady_clock();
    std::shared_ptr<Timers> timers_ = std::make_shared<Timers>();
    TimerId next_timer_ = 1;
    std::thread thread_;  // last: starts once the loop exists; none on a shared loop
};

}  // namespace loopwire::gateway
