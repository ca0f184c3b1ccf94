// DeviceClient::read_async, the gateway's non-blocking poll: it reads what read() reads, block
// after block from each completion; on the first timeout or link failure it stops, failing the
// blocks not yet asked with that error unsent (a silent device costs one timeout per poll); a
// block the device refuses with an exception is asked again parameter by parameter; a requested
// stop ends it before the next block.
#include <gtest/gtest.h>

#include <optional>
#include <stop_token>
#include <string>
#include <vector>

#include "client/device_client.hpp"
#include "profile/request_planner.hpp"
#include "support/profile_test_support.hpp"

namespace loopwire::device {
namespace {

// Answers reads from a script: register r holds r * 3 + 1, unless the script says every request
// times out, or that requests for more than one word are refused (exception 02h).
class ScriptedRegisters final : public session::Master {
public:
    enum class Mode { answer, time_out, refuse_blocks };
    explicit ScriptedRegisters(Mode mode) : mode_(mode) {}

    Result<codec::Reply> execute(std::uint8_t, const codec::Request& request) override {
        asked.push_back(request);
        if (mode_ == Mode::time_out) return make_error(ErrorKind::timeout, "unit 3: no reply within 300 ms");
        if (mode_ == Mode::refuse_blocks && request.count > 1) {
            return make_error(ErrorKind::exception, "unit 3 answered exception 02h (illegal data address)", 0x02);
        }
        codec::Reply reply;
        reply.function = request.function;
        for (std::uint16_t i = 0; i < request.count; ++i) reply.values.push_back(static_cast<std::uint16_t>((request.address + i) * 3 + 1));
        return reply;
    }
    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override { done(execute(unit, request)); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return make_error(ErrorKind::usage, "reads only"); }
    void forward_async(std::uint8_t, Bytes, ForwardCompletion done) override { done(make_error(ErrorKind::usage, "reads only")); }
    std::string describe() const override { return "scripted registers"; }

    std::vector<codec::Request> asked;

private:
    Mode mode_;
};

struct Outcome {
    ReadReport report;
    std::optional<Error> stopped_by;
};

// Every readable parameter of the TC10: several blocks.
std::vector<const Parameter*> all_readable(const Profile& profile) {
    std::vector<const Parameter*> readable;
    for (const auto& parameter : profile.parameters) {
        if (parameter.readable) readable.push_back(&parameter);
    }
    return readable;
}

class ReadAsync : public ::testing::Test {
protected:
    Outcome read_async(session::Master& master, const std::vector<const Parameter*>& wanted, std::stop_token stop = {}) {
        DeviceClient client(master, address);
        std::optional<Outcome> outcome;
        client.read_async(wanted, std::move(stop), [&](ReadReport report, std::optional<Error> stopped_by) {
            EXPECT_FALSE(outcome.has_value()) << "done ran twice";
            outcome = Outcome{std::move(report), std::move(stopped_by)};
        });
        EXPECT_TRUE(outcome.has_value()) << "done never ran";
        return outcome.value_or(Outcome{});
    }

    std::size_t blocks_of(const std::vector<const Parameter*>& wanted) const {
        return plan_reads(*address.profile, wanted, 0).size();
    }

    DeviceAddress address = *parse_device_address(testing::builtin_registry(), "tc10@3");
    std::vector<const Parameter*> parameters = all_readable(*address.profile);
};

TEST_F(ReadAsync, ReadsWhatReadReads) {
    ASSERT_GE(blocks_of(parameters), 2U) << "the test needs a read of several blocks";
    ScriptedRegisters blocking(ScriptedRegisters::Mode::answer);
    const ReadReport expected = DeviceClient(blocking, address).read(parameters);
    ScriptedRegisters asynchronous(ScriptedRegisters::Mode::answer);
    const Outcome got = read_async(asynchronous, parameters);

    EXPECT_FALSE(got.stopped_by.has_value());
    EXPECT_EQ(asynchronous.asked, blocking.asked);
    EXPECT_EQ(got.report.requests, expected.requests);
    EXPECT_EQ(got.report.raw, expected.raw);
    ASSERT_EQ(got.report.readings.size(), expected.readings.size());
    for (std::size_t i = 0; i < expected.readings.size(); ++i) {
        const auto& want = expected.readings[i];
        const auto& have = got.report.readings[i];
        EXPECT_EQ(have.parameter, want.parameter);
        EXPECT_EQ(have.error, want.error) << want.parameter->name;
        ASSERT_EQ(have.value.has_value(), want.value.has_value()) << want.parameter->name;
        if (want.value) {
            EXPECT_EQ(have.value->raw, want.value->raw) << want.parameter->name;
        }
    }
}

TEST_F(ReadAsync, TheFirstTimeoutEndsThePollAndFailsTheRestUnsent) {
    ScriptedRegisters silent(ScriptedRegisters::Mode::time_out);
    const Outcome got = read_async(silent, parameters);
    EXPECT_EQ(silent.asked.size(), 1U) << "a silent device cost more than one timeout";
    ASSERT_TRUE(got.stopped_by.has_value());
    EXPECT_EQ(got.stopped_by->kind, ErrorKind::timeout);
    EXPECT_EQ(got.report.requests, 1U);
    ASSERT_TRUE(got.report.first_error.has_value());
    for (const auto& reading : got.report.readings) {
        EXPECT_FALSE(reading.value.has_value()) << reading.parameter->name;
        EXPECT_EQ(reading.error, "unit 3: no reply within 300 ms") << reading.parameter->name;
    }
}

TEST_F(ReadAsync, ABlockRefusedWithAnExceptionIsAskedParameterByParameter) {
    ScriptedRegisters picky(ScriptedRegisters::Mode::refuse_blocks);
    const Outcome got = read_async(picky, parameters);
    EXPECT_FALSE(got.stopped_by.has_value());
    for (const Parameter* parameter : parameters) {
        EXPECT_EQ(got.report.raw.count(parameter->name), 1U) << parameter->name << " was not read";
    }
    std::size_t singles = 0;
    for (const auto& request : picky.asked) singles += request.count == 1;
    EXPECT_GT(singles, 0U);
    EXPECT_EQ(got.report.requests, picky.asked.size());
    ScriptedRegisters blocking(ScriptedRegisters::Mode::refuse_blocks);
    (void)DeviceClient(blocking, address).read(parameters);
    EXPECT_EQ(picky.asked, blocking.asked) << "not the requests read() sends";
}

TEST_F(ReadAsync, AStopRequestedEndsItBeforeTheNextBlock) {
    std::stop_source stop;
    stop.request_stop();
    ScriptedRegisters master(ScriptedRegisters::Mode::answer);
    const Outcome got = read_async(master, parameters, stop.get_token());
    EXPECT_TRUE(master.asked.empty());
    ASSERT_TRUE(got.stopped_by.has_value());
    EXPECT_EQ(got.stopped_by->message, "polling stopped");
    for (const auto& reading : got.report.readings) EXPECT_FALSE(reading.value.has_value());
}

}  // namespace
}  // namespace loopwire::device
