#pragma once
// A fake byte pipe that plays a script: it asserts the exact bytes the master writes and answers
// each write with scripted bytes. The manuals' example exchanges are ready-made scripts.
// On the steady clock it waits in wall time; given a VirtualClock it waits in virtual time: a
// read jumps the clock to the scripted answer's arrival, or to the end of its timeout when
// nothing arrives by then (common/clock.hpp).
#include <gtest/gtest.h>

#include <chrono>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>

#include "common/bytes.hpp"
#include "common/clock.hpp"
#include "support/test_bytes.hpp"
#include "transport/byte_stream.hpp"

namespace loopwire::testing {

struct ScriptStep {
    Bytes expect;                        // what the master must write
    std::optional<Bytes> answer;         // what the line carries back (nullopt: silence)
    std::chrono::milliseconds delay{0};  // how long after the write the answer arrives
};

class ScriptedStream final : public transport::ByteStream {
public:
    using Clock = std::chrono::steady_clock;

    explicit ScriptedStream(std::deque<ScriptStep> script, std::shared_ptr<VirtualClock> virtual_clock = nullptr)
        : script_(std::move(script)), virtual_clock_(std::move(virtual_clock)) {}

    Result<void> write(ByteView bytes) override {
        std::lock_guard lock(mutex_);
        writes_.push_back({now(), Bytes(bytes.begin(), bytes.end())});
        if (script_.empty()) {
            ADD_FAILURE() << "unexpected write " << to_hex(bytes);
            return {};
        }
        ScriptStep step = std::move(script_.front());
        script_.pop_front();
        EXPECT_EQ(to_hex(bytes), to_hex(step.expect));
        if (step.answer) {
            pending_ = *step.answer;
            due_ = now() + step.delay;
        }
        return {};
    }

    Result<std::size_t> read_some(std::span<std::uint8_t> buffer, std::chrono::milliseconds timeout) override {
        if (virtual_clock_) return read_in_virtual_time(buffer, timeout);
        const auto until = Clock::now() + timeout;
        for (;;) {
            {
                std::lock_guard lock(mutex_);
                if (!pending_.empty() && Clock::now() >= due_) return deliver(buffer);
            }
            if (Clock::now() >= until) return std::size_t{0};
            std::this_thread::sleep_for(std::chrono::microseconds(200));
        }
    }

    void discard_input() override {}
    int poll_handle() const override { return -1; }
    std::string describe() const override { return "scripted stream"; }

    struct Write {
        Clock::time_point at;
        Bytes bytes;
    };
    std::vector<Write> writes() const {
        std::lock_guard lock(mutex_);
        return writes_;
    }
    // When the last answer bytes were handed to the reader: the earliest moment the reader
    // can have seen the end of a reply.
    Clock::time_point last_delivery() const {
        std::lock_guard lock(mutex_);
        return delivered_;
    }
    bool script_done() const {
        std::lock_guard lock(mutex_);
        return script_.empty();
    }

private:
    Clock::time_point now() const { return virtual_clock_ ? virtual_clock_->now() : Clock::now(); }

    // Nothing else runs on the virtual clock while the master reads, so waiting is jumping.
    Result<std::size_t> read_in_virtual_time(std::span<std::uint8_t> buffer, std::chrono::milliseconds timeout) {
        std::lock_guard lock(mutex_);
        const auto until = virtual_clock_->now() + timeout;
        if (pending_.empty() || due_ > until) {
            virtual_clock_->sleep_until(until);
            return std::size_t{0};
        }
        virtual_clock_->sleep_until(due_);
        return deliver(buffer);
    }

    // Called with mutex_ held.
    std::size_t deliver(std::span<std::uint8_t> buffer) {
        const std::size_t n = std::min(buffer.size(), pending_.size());
        std::copy_n(pending_.begin(), n, buffer.begin());
        pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n));
        delivered_ = now();
        return n;
    }

    mutable std::mutex mutex_;
    std::deque<ScriptStep> script_;
    Bytes pending_;
    Clock::time_point due_{};
    Clock::time_point delivered_{};
    std::vector<Write> writes_;
    std::shared_ptr<VirtualClock> virtual_clock_;
};


}  // namespace loopwire::testing
