// Raw registers read and polled (client/register_monitor.hpp) against a scripted master: a range
// split into requests of at most per_request, a failed poll counted and the polling going on,
// and the samples taken on the monitors' one loop until its count.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <mutex>
#include <stop_token>
#include <vector>

#include "client/register_monitor.hpp"

namespace loopwire::device {
namespace {

using namespace std::chrono_literals;

// Answers each read with words equal to their addresses, except the requests numbered in
// `failing` (0-based), which time out.
class AddressEcho final : public Master {
public:
    explicit AddressEcho(std::vector<unsigned> failing = {}) : failing_(std::move(failing)) {}

    Result<codec::Reply> execute(std::uint8_t unit, const codec::Request& request) override {
        std::lock_guard lock(mutex_);
        const unsigned number = static_cast<unsigned>(requests.size());
        requests.push_back({unit, request.function, request.address, request.count});
        if (std::find(failing_.begin(), failing_.end(), number) != failing_.end()) return make_error(ErrorKind::timeout, "no reply");
        codec::Reply reply;
        reply.function = request.function;
        for (std::uint16_t i = 0; i < request.count; ++i) reply.values.push_back(static_cast<std::uint16_t>(request.address + i));
        return reply;
    }
    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override { done(execute(unit, request)); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return make_error(ErrorKind::usage, "not scripted"); }
    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override { done(forward(unit, pdu)); }
    std::string describe() const override { return "address echo"; }

    struct Asked {
        std::uint8_t unit;
        std::uint8_t function;
        std::uint16_t address;
        std::uint16_t count;
        bool operator==(const Asked&) const = default;
    };
    std::vector<Asked> requests;

private:
    std::mutex mutex_;
    std::vector<unsigned> failing_;
};

TEST(RegisterMonitor, ARangeIsReadInRequestsOfAtMostPerRequest) {
    AddressEcho master;
    const RegisterRange range{5, codec::FunctionCode::read_input_registers, 100, 5, 2};
    auto words = read_registers(master, range);
    ASSERT_TRUE(words) << words.error().message;
    EXPECT_EQ(*words, (std::vector<std::uint16_t>{100, 101, 102, 103, 104}));
    const auto input = static_cast<std::uint8_t>(codec::FunctionCode::read_input_registers);
    EXPECT_EQ(master.requests, (std::vector<AddressEcho::Asked>{{5, input, 100, 2}, {5, input, 102, 2}, {5, input, 104, 1}}));
}

TEST(RegisterMonitor, TheFirstFailedRequestEndsARead) {
    AddressEcho master({1});
    auto words = read_registers(master, RegisterRange{1, codec::FunctionCode::read_holding_registers, 0, 6, 2});
    ASSERT_FALSE(words);
    EXPECT_EQ(words.error().kind, ErrorKind::timeout);
    EXPECT_EQ(master.requests.size(), 2u);
}

TEST(RegisterMonitor, PollsUntilItsCountAndCountsFailedPollsWithoutStopping) {
    AddressEcho master({1});  // the second poll times out
    MonitorSettings settings;
    settings.interval = 1ms;
    settings.count = 3;
    std::vector<RegisterSample> samples;
    run_register_monitor(master, RegisterRange{2, codec::FunctionCode::read_holding_registers, 40, 2, 125}, settings,
                         [&samples](const RegisterSample& sample) { samples.push_back(sample); }, std::stop_source().get_token());
    ASSERT_EQ(samples.size(), 3u);
    EXPECT_EQ(samples[0].index, 1u);
    EXPECT_EQ(samples[0].words, (std::vector<std::uint16_t>{40, 41}));
    EXPECT_FALSE(samples[0].error);
    EXPECT_EQ(samples[0].errors, 0u);
    ASSERT_TRUE(samples[1].error);
    EXPECT_EQ(samples[1].error->kind, ErrorKind::timeout);
    EXPECT_TRUE(samples[1].words.empty());
    EXPECT_EQ(samples[1].errors, 1u);
    EXPECT_EQ(samples[2].index, 3u);
    EXPECT_EQ(samples[2].words, (std::vector<std::uint16_t>{40, 41}));
    EXPECT_EQ(samples[2].errors, 1u);  // failed polls so far, not reset by a good one
    EXPECT_LE(samples[0].time, samples[2].time);
}

TEST(RegisterMonitor, AStopEndsThePolling) {
    AddressEcho master;
    MonitorSettings settings;
    settings.interval = 1ms;  // no count: only the stop ends it
    std::stop_source stop;
    unsigned written = 0;
    run_register_monitor(master, RegisterRange{}, settings,
                         [&](const RegisterSample& sample) {
                             ++written;
                             if (sample.index == 2) stop.request_stop();
                         },
                         stop.get_token());
    EXPECT_EQ(written, 2u);
}

}  // namespace
}  // namespace loopwire::device
