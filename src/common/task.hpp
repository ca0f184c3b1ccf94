#pragma once
// A C++20 coroutine that produces one value: how the serial master's exchange is written once
// and run two ways (session/serial_master.cpp). Its waits are awaitables that either complete
// at once, by blocking the calling thread (a command-line tool's master), or suspend the
// coroutine until a shared loop resumes it (session/line_loop.hpp: a gateway's lines on one
// thread). The same code therefore carries both, and the virtual-time tests of the blocking
// path test the rules the loop runs.
//
// Lazy: the body starts when the task is awaited or started. Awaiting a task resumes the
// awaiter when it ends (symmetric transfer, no stack growth per hop). Exceptions are not part
// of this code base's error handling (Result is): one escaping a task ends the process.
#include <coroutine>
#include <cstdlib>
#include <exception>
#include <functional>
#include <optional>
#include <utility>

namespace loopwire {

template <typename T>
class [[nodiscard]] Task {
public:
    struct promise_type {
        std::optional<T> value;
        std::coroutine_handle<> continuation;

        Task get_return_object() { return Task(std::coroutine_handle<promise_type>::from_promise(*this)); }
        std::suspend_always initial_suspend() noexcept { return {}; }

        struct Ending {
            bool await_ready() noexcept { return false; }
            std::coroutine_handle<> await_suspend(std::coroutine_handle<promise_type> ending) noexcept {
                auto next = ending.promise().continuation;
                return next ? next : std::noop_coroutine();
            }
            void await_resume() noexcept {}
        };
        Ending final_suspend() noexcept { return {}; }

        void return_value(T result) { value.emplace(std::move(result)); }
        void unhandled_exception() noexcept { std::terminate(); }
    };

    Task(Task&& other) noexcept : handle_(std::exchange(other.handle_, {})) {}
    Task& operator=(Task&& other) noexcept {
        if (this != &other) {
            if (handle_) handle_.destroy();
            handle_ = std::exchange(other.handle_, {});
        }
        return *this;
    }
    Task(const Task&) = delete;
    Task& operator=(const Task&) = delete;
    ~Task() {
        if (handle_) handle_.destroy();
    }

    // co_await task: runs it, resumes here with its value.
    bool await_ready() const noexcept { return false; }
    std::coroutine_handle<> await_suspend(std::coroutine_handle<> awaiting) noexcept {
        handle_.promise().continuation = awaiting;
        return handle_;
    }
    T await_resume() { return std::move(*handle_.promise().value); }

    // Runs the task on this thread until it ends or first suspends; whether it has ended.
    bool run_until_suspended() {
        handle_.resume();
        return handle_.done();
    }
    // The value of a task that has ended.
    T take() { return std::move(*handle_.promise().value); }

private:
    explicit Task(std::coroutine_handle<promise_type> handle) : handle_(handle) {}
    std::coroutine_handle<promise_type> handle_;
};

// Runs a task whose waits all complete at once (they block instead of suspending) and returns
// its value. A task that suspends anyway was given a wait that belongs to a loop: a bug, which
// ends the process rather than return a value that is not there.
template <typename T>
T run_blocking(Task<T> task) {
    if (!task.run_until_suspended()) std::abort();
    return task.take();
}

// A started task that nobody awaits: `done` gets its value when it ends, on the thread that
// resumed it last. Destroying the handle before then (a loop shutting down) destroys the task
// and its callback without calling it.
class DetachedTask {
public:
    struct promise_type {
        DetachedTask get_return_object() {
            return DetachedTask(std::coroutine_handle<promise_type>::from_promise(*this));
        }
        std::suspend_always initial_suspend() noexcept { return {}; }
        std::suspend_always final_suspend() noexcept { return {}; }
        void return_void() noexcept {}
        void unhandled_exception() noexcept { std::terminate(); }
    };

    DetachedTask(DetachedTask&& other) noexcept : handle_(std::exchange(other.handle_, {})) {}
    DetachedTask& operator=(DetachedTask&& other) noexcept {
        if (this != &other) {
            if (handle_) handle_.destroy();
            handle_ = std::exchange(other.handle_, {});
        }
        return *this;
    }
    DetachedTask(const DetachedTask&) = delete;
    DetachedTask& operator=(const DetachedTask&) = delete;
    ~DetachedTask() {
        if (handle_) handle_.destroy();
    }

    // Runs until the first suspension (or the end, if nothing waits).
    void start() { handle_.resume(); }

private:
    explicit DetachedTask(std::coroutine_handle<promise_type> handle) : handle_(handle) {}
    std::coroutine_handle<promise_type> handle_;
};

// Wraps `task` so that its value goes to `done`. The frame stays until the returned object goes,
// so a caller keeps it while the task runs and drops it once `done` has been called (not from
// inside `done`: the frame is still running it).
template <typename T>
DetachedTask deliver(Task<T> task, std::function<void(T)> done) {
    done(co_await task);
}

}  // namespace loopwire
