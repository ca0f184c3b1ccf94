#pragma once
// A line in virtual time for slave-side tests (session and device tests share it).
#include <algorithm>
#include <deque>
#include <memory>
#include <stop_token>
#include <vector>

#include "common/bytes.hpp"
#include "common/clock.hpp"
#include "transport/byte_stream.hpp"

namespace loopwire::testing {

// The slave's end of a line in virtual time: requests arrive at the instants a test gives, and
// every write is kept with the virtual instant it was made. A read jumps the clock to the next
// arrival, or to the end of its timeout; a read that finds nothing left to arrive asks the
// slave to stop, so serve_stream runs on the test's thread and returns when the line is done.
class VirtualLine final : public transport::ByteStream {
public:
    VirtualLine(std::shared_ptr<VirtualClock> clock, std::stop_source stop) : clock_(std::move(clock)), stop_(std::move(stop)) {}

    struct Write {
        Instant at;
        Bytes bytes;
    };

    void arrive(Instant at, Bytes bytes) { inbox_.push_back({at, std::move(bytes)}); }
    const std::vector<Write>& writes() const { return writes_; }

    Result<void> write(ByteView bytes) override {
        writes_.push_back({clock_->now(), Bytes(bytes.begin(), bytes.end())});
        return {};
    }

    Result<std::size_t> read_some(std::span<std::uint8_t> buffer, std::chrono::milliseconds timeout) override {
        const Instant until = clock_->now() + timeout;
        if (inbox_.empty() || inbox_.front().at > until) {
            clock_->sleep_until(until);
            if (inbox_.empty()) stop_.request_stop();
            return std::size_t{0};
        }
        clock_->sleep_until(inbox_.front().at);
        Bytes& next = inbox_.front().bytes;
        const std::size_t count = std::min(buffer.size(), next.size());
        std::copy_n(next.begin(), count, buffer.begin());
        next.erase(next.begin(), next.begin() + static_cast<std::ptrdiff_t>(count));
        if (next.empty()) inbox_.pop_front();
        return count;
    }

    void discard_input() override {}
    int poll_handle() const override { return -1; }
    std::string describe() const override { return "virtual line"; }

private:
    struct Arrival {
        Instant at;
        Bytes bytes;
    };
    std::shared_ptr<VirtualClock> clock_;
    std::stop_source stop_;
    std::deque<Arrival> inbox_;
    std::vector<Write> writes_;
};

}  // namespace loopwire::testing
