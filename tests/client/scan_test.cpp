// The unit scan (client/scan.hpp): a sweep lists each device once with every setting it answered
// at, a gateway's 0Ah/0Bh is nobody, garbled lines are reported, a stop ends the scan with what
// it found; and the plan refuses sweeps it cannot make.
#include <gtest/gtest.h>

#include <chrono>
#include <stop_token>
#include <string>
#include <vector>

#include "client/scan.hpp"
#include "faulty_bus_rig.hpp"

namespace loopwire::device {
namespace {

using namespace std::chrono_literals;

// A master whose answers a test writes: `answer(unit)` decides each request; each request also
// traces `garbled` discarded runs of bytes, as a serial master at a wrong baud rate would.
class ScriptedLine final : public session::Master {
public:
    ScriptedLine(std::function<Result<codec::Reply>(std::uint8_t)> answer, session::TraceSink trace, unsigned garbled = 0)
        : answer_(std::move(answer)), trace_(std::move(trace)), garbled_(garbled) {}

    Result<codec::Reply> execute(std::uint8_t unit, const codec::Request&) override {
        for (unsigned i = 0; i < garbled_ && trace_; ++i) trace_({{}, session::TraceDirection::discarded, {0xFF}, "bad CRC"});
        return answer_(unit);
    }
    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override { done(execute(unit, request)); }
    Result<Bytes> forward(std::uint8_t, ByteView) override { return make_error(ErrorKind::usage, "not scripted"); }
    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override { done(forward(unit, pdu)); }
    std::string describe() const override { return "scripted line"; }

private:
    std::function<Result<codec::Reply>(std::uint8_t)> answer_;
    session::TraceSink trace_;
    unsigned garbled_;
};

// Passes every request to a master someone else owns.
class Borrowed final : public session::Master {
public:
    explicit Borrowed(session::Master& master) : master_(master) {}
    Result<codec::Reply> execute(std::uint8_t unit, const codec::Request& request) override { return master_.execute(unit, request); }
    void execute_async(std::uint8_t unit, codec::Request request, Completion done) override {
        master_.execute_async(unit, std::move(request), std::move(done));
    }
    Result<Bytes> forward(std::uint8_t unit, ByteView pdu) override { return master_.forward(unit, pdu); }
    void forward_async(std::uint8_t unit, Bytes pdu, ForwardCompletion done) override { master_.forward_async(unit, std::move(pdu), std::move(done)); }
    std::string describe() const override { return master_.describe(); }

private:
    session::Master& master_;
};

Error timed_out() { return make_error(ErrorKind::timeout, "no reply"); }
Error exception(int code) { return make_error(ErrorKind::exception, "exception reply", code); }

struct Recorded {
    std::vector<std::string> tried;                           // "LINE unit N"
    std::vector<std::vector<std::string>> found_lines;        // `lines` of each found event
    std::vector<std::pair<std::size_t, unsigned>> line_done;  // (answered, garbled) per setting
};

ScanEvents recording(Recorded& recorded) {
    ScanEvents events;
    events.trying = [&recorded](const std::string& line, int unit, std::size_t, std::size_t, std::size_t) {
        recorded.tried.push_back(line + " unit " + std::to_string(unit));
    };
    events.found = [&recorded](const FoundUnit& unit) { recorded.found_lines.push_back(unit.lines); };
    events.line_done = [&recorded](const std::string&, std::size_t answered, unsigned garbled) { recorded.line_done.emplace_back(answered, garbled); };
    return events;
}

TEST(UnitScan, ASweepListsEachDeviceOnceWithEverySettingItAnsweredAt) {
    app::testing::FaultyBusRig rig({"tc10@3"}, 500ms);
    auto scan = UnitScan::plan("rtu:/dev/ttyUSB0?baud=9600", {"9600", "19200"}, {"none", "e"});
    ASSERT_TRUE(scan.ok()) << scan.error().message;
    EXPECT_EQ(scan->settings_text(), (std::vector<std::string>{"9600 8N1", "9600 8E1", "19200 8N1", "19200 8E1"}));
    // The TC10 answers at 19200 only; at 9600 the line is all garbage.
    MasterOpener open = [&rig](const transport::LinkUrl& url, session::MasterOptions options) -> Result<std::unique_ptr<session::Master>> {
        if (url.serial.baud == 19200) return std::unique_ptr<session::Master>(std::make_unique<Borrowed>(rig.master()));
        return std::unique_ptr<session::Master>(std::make_unique<ScriptedLine>([](std::uint8_t) { return Result<codec::Reply>(timed_out()); }, options.trace, 2));
    };
    Recorded recorded;
    auto result = scan->run({3}, 500ms, {}, recording(recorded), std::stop_source().get_token(), open);
    ASSERT_TRUE(result.ok()) << result.error().message;
    ASSERT_EQ(result->found.size(), 1u);
    EXPECT_EQ(result->found[0].unit, 3);
    EXPECT_EQ(result->found[0].device, "tc10");
    EXPECT_EQ(result->found[0].line, "19200 8N1");
    EXPECT_EQ(result->found[0].lines, (std::vector<std::string>{"19200 8N1", "19200 8E1"}));
    EXPECT_EQ(result->found_per_line, (std::vector<std::vector<int>>{{}, {}, {3}, {3}}));
    EXPECT_FALSE(ignores_line_settings(result->found_per_line));
    EXPECT_FALSE(result->interrupted);
    // Each answer is reported as it comes: first new, then again with the second setting.
    EXPECT_EQ(recorded.found_lines, (std::vector<std::vector<std::string>>{{"19200 8N1"}, {"19200 8N1", "19200 8E1"}}));
    ASSERT_EQ(recorded.line_done.size(), 4u);
    EXPECT_EQ(recorded.line_done[0], (std::pair<std::size_t, unsigned>{0, 2}));
    EXPECT_EQ(recorded.line_done[2].first, 1u);
    EXPECT_EQ(recorded.tried.front(), "9600 8N1 unit 3");
}

TEST(UnitScan, AGatewaySayingNothingIsThereIsNobodyButAnyOtherExceptionIsADevice) {
    auto scan = UnitScan::plan("tcp://127.0.0.1:1502", {}, {});
    ASSERT_TRUE(scan.ok()) << scan.error().message;
    MasterOpener open = [](const transport::LinkUrl&, session::MasterOptions options) -> Result<std::unique_ptr<session::Master>> {
        return std::unique_ptr<session::Master>(std::make_unique<ScriptedLine>(
            [](std::uint8_t unit) {
                if (unit == 5) return Result<codec::Reply>(exception(2));  // a device refusing the address
                if (unit == 6) return Result<codec::Reply>(timed_out());
                return Result<codec::Reply>(exception(unit == 1 ? 0x0A : 0x0B));
            },
            options.trace));
    };
    Recorded recorded;
    auto result = scan->run({1, 2, 5, 6}, 100ms, {}, recording(recorded), std::stop_source().get_token(), open);
    ASSERT_TRUE(result.ok()) << result.error().message;
    ASSERT_EQ(result->found.size(), 1u);
    EXPECT_EQ(result->found[0].unit, 5);
    EXPECT_EQ(result->found[0].device, "");  // no profile's identification words hold
    EXPECT_EQ(result->gateway_refusals, 2u);
    EXPECT_EQ(recorded.tried.size(), 4u);
}

TEST(UnitScan, AStopEndsTheScanWithWhatItFound) {
    auto scan = UnitScan::plan("tcp://127.0.0.1:1502", {}, {});
    ASSERT_TRUE(scan.ok());
    MasterOpener open = [](const transport::LinkUrl&, session::MasterOptions options) -> Result<std::unique_ptr<session::Master>> {
        return std::unique_ptr<session::Master>(std::make_unique<ScriptedLine>([](std::uint8_t) { return Result<codec::Reply>(exception(1)); }, options.trace));
    };
    std::stop_source stop;
    Recorded recorded;
    auto events = recording(recorded);
    events.found = [&stop](const FoundUnit&) { stop.request_stop(); };  // Ctrl-C after the first unit
    auto result = scan->run({1, 2, 3}, 100ms, {}, events, stop.get_token(), open);
    ASSERT_TRUE(result.ok());
    EXPECT_TRUE(result->interrupted);
    ASSERT_EQ(result->found.size(), 1u);
    EXPECT_EQ(recorded.tried.size(), 1u);
}

TEST(UnitScan, ALinkThatCannotBeOpenedEndsTheScanWithItsError) {
    auto scan = UnitScan::plan("rtu:/dev/ttyUSB0", {"9600", "19200"}, {});
    ASSERT_TRUE(scan.ok());
    MasterOpener open = [](const transport::LinkUrl& url, session::MasterOptions) -> Result<std::unique_ptr<session::Master>> {
        return make_error(ErrorKind::link, "cannot open at " + std::to_string(url.serial.baud));
    };
    auto result = scan->run({1}, 100ms, {}, {}, std::stop_source().get_token(), open);
    ASSERT_FALSE(result.ok());
    EXPECT_EQ(result.error().message, "cannot open at 9600");
}

TEST(UnitScan, PlanRefusesWhatCannotBeSwept) {
    auto network = UnitScan::plan("tcp://127.0.0.1:502", {"9600"}, {});
    ASSERT_FALSE(network.ok());
    EXPECT_NE(network.error().message.find("is a network link"), std::string::npos);
    auto baud = UnitScan::plan("rtu:/dev/ttyUSB0", {"12345"}, {});
    ASSERT_FALSE(baud.ok());
    EXPECT_NE(baud.error().message.find("baud 12345 is not a supported rate"), std::string::npos);
    auto parity = UnitScan::plan("rtu:/dev/ttyUSB0", {}, {"mark"});
    ASSERT_FALSE(parity.ok());
    EXPECT_EQ(parity.error().message, "parity 'mark' is not none, even or odd");
    auto own = UnitScan::plan("rtu:/dev/ttyUSB0?baud=38400&parity=odd", {}, {});
    ASSERT_TRUE(own.ok());
    EXPECT_EQ(own->settings_text(), std::vector<std::string>{"38400 8O1"});
}

TEST(UnitScan, SameUnitsAtEverySettingMeanTheLineIgnoresThem) {
    EXPECT_TRUE(ignores_line_settings({{1, 3}, {1, 3}, {1, 3}}));
    EXPECT_FALSE(ignores_line_settings({{1, 3}, {}, {}}));  // found at one setting only: a real line
    EXPECT_FALSE(ignores_line_settings({{1, 3}}));          // nothing swept
    EXPECT_FALSE(ignores_line_settings({{}, {}}));          // nobody answered
    EXPECT_FALSE(ignores_line_settings({{1}, {1, 3}}));
}

}  // namespace
}  // namespace loopwire::device
