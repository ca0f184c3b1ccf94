#pragma once
// Runs queued jobs in order on one thread of its own, started on first use: what a master's
// *_async calls hand their blocking work to. Destroying it runs the jobs still queued, then
// joins the thread, so it must not be destroyed by one of its own jobs.
//
// WhenIdle::end_thread: the thread ends once the queue is empty and the next push starts
// another, for work that comes rarely (reopening a line whose requests are carried elsewhere),
// so that an idle queue holds no thread.
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "common/thread_name.hpp"

namespace loopwire::session {

class JobQueue {
public:
    // `thread_name`: what its thread is called (common/thread_name.hpp).
    enum class WhenIdle { keep_thread, end_thread };

    explicit JobQueue(std::string thread_name = "lw-jobs", WhenIdle when_idle = WhenIdle::keep_thread)
        : thread_name_(std::move(thread_name)), when_idle_(when_idle) {}
    JobQueue(const JobQueue&) = delete;
    JobQueue& operator=(const JobQueue&) = delete;

    ~JobQueue() { finish(); }

    // Runs the jobs still queued, then joins the thread. A job pushed afterwards still runs, on
    // a thread started for it and joined by the next finish() or the destructor.
    void finish() {
        {
            std::lock_guard lock(mutex_);
            stopping_ = true;
        }
        ready_.notify_all();
        if (worker_.joinable()) worker_.join();
    }

    void push(std::function<void()> job) {
        std::lock_guard lock(mutex_);
        // A thread that ended for want of work has released the lock for good: joined at once.
        if (ended_ && worker_.joinable()) worker_.join();
        if (!worker_.joinable()) {
            ended_ = false;
            worker_ = std::thread([this] { run(); });
            name_thread(worker_.native_handle(), thread_name_);
        }
        jobs_.push_back(std::move(job));
        ready_.notify_one();
    }

private:
    void run() {
        std::unique_lock lock(mutex_);
        for (;;) {
            ready_.wait(lock, [this] { return stopping_ || !jobs_.empty() || when_idle_ == WhenIdle::end_thread; });
            if (jobs_.empty()) {  // stopping, or idle and ending
                ended_ = true;
                return;
            }
            auto job = std::move(jobs_.front());
            jobs_.pop_front();
            lock.unlock();
            job();
            lock.lock();
        }
    }

    std::mutex mutex_;
    std::condition_variable ready_;
    std::deque<std::function<void()>> jobs_;
    bool stopping_ = false;
    bool ended_ = false;  // the thread has returned (WhenIdle::end_thread) and wants joining
    std::string thread_name_;
    WhenIdle when_idle_;
    std::thread worker_;
};

}  // namespace loopwire::session
