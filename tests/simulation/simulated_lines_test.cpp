// Several virtual lines' simulated devices served from one thread, the lines' loop
// (simulation/simulated_lines.hpp): every line answered correctly, one thread for all, and no
// line's reply held up by another's.
#include <gtest/gtest.h>

#include <future>
#include <string>
#include <thread>

#include "session/line_loop.hpp"
#include "session/master.hpp"
#include "simulation/register_bank.hpp"
#include "simulation/simulated_lines.hpp"
#include "support/thread_names.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::simulation {
namespace {

using namespace std::chrono_literals;

struct Line {
    transport::LinkUrl link;
    std::shared_ptr<transport::VirtualBus> bus;
    std::shared_ptr<session::RegisterBank> bank = std::make_shared<session::RegisterBank>();
};

Line served_line(SimulatedLines& lines, std::uint32_t baud) {
    Line line;
    line.link = *transport::parse_link_url("rtu:virtual?baud=" + std::to_string(baud));
    line.bus = transport::VirtualBus::create(baud, line.link.serial.bits_per_character());
    auto added = lines.add(line.bus->attach("devices", transport::VirtualBus::Writes::return_at_once),
                           std::make_unique<session::Slave>(line.link, session::UnitMap{{1, line.bank}}));
    EXPECT_TRUE(added) << added.error().message;
    return line;
}

// `retries`: a loaded, sanitised test machine can stretch a frame past its gaps.
std::unique_ptr<session::Master> master_on(const Line& line, std::chrono::milliseconds timeout, unsigned retries = 2) {
    session::MasterOptions options;
    options.timeout = timeout;
    options.retries = retries;
    return session::make_serial_master(line.bus->attach("master"), line.link, options);
}

codec::Request read_holding(std::uint16_t address, std::uint16_t count) {
    return codec::read_request(codec::FunctionCode::read_holding_registers, address, count);
}

TEST(SimulatedLines, OneThreadAnswersTheDevicesOfEveryLine) {
    SimulatedLines lines(std::make_shared<session::LineLoop>());
    std::vector<Line> served;
    for (std::uint16_t i = 0; i < 4; ++i) {
        served.push_back(served_line(lines, 19200));
        served.back().bank->set(codec::Table::holding_registers, 10, static_cast<std::uint16_t>(100 + i));
    }
    EXPECT_EQ(lines.lines(), 4U);
    EXPECT_EQ(testing::thread_names().count("lw-lines"), 1U);
    // All four lines asked at once, 20 times each: every reply the right one.
    std::vector<std::future<int>> answered;
    for (std::uint16_t i = 0; i < 4; ++i) {
        answered.push_back(std::async(std::launch::async, [&line = served[i], i] {
            auto master = master_on(line, 2s);
            int right = 0;
            for (int n = 0; n < 20; ++n) {
                auto reply = master->execute(1, read_holding(10, 1));
                if (reply && reply->values == std::vector<std::uint16_t>{static_cast<std::uint16_t>(100 + i)}) ++right;
            }
            return right;
        }));
    }
    for (auto& line : answered) EXPECT_EQ(line.get(), 20);
    EXPECT_EQ(lines.failed(), 0U);
}

// Line A's reply takes 1.9 s of wire time at 1200 baud; while it is on the wire, line B at
// 115200 baud is asked with a 1 s timeout. Had the shared thread waited for A's wire, B's reply
// would come after A's had left, too late.
TEST(SimulatedLines, AReplyOnOneLineDoesNotWaitForAnotherLinesWire) {
    SimulatedLines lines(std::make_shared<session::LineLoop>());
    Line slow = served_line(lines, 1200);
    Line fast = served_line(lines, 115200);
    fast.bank->set(codec::Table::holding_registers, 0, 4242);
    auto listener = slow.bus->attach("listener");  // hears the slow reply start
    auto slow_read = std::async(std::launch::async, [&slow] { return master_on(slow, 10s)->execute(1, read_holding(0, 100)); });
    // Past the request (8 bytes), the first byte of the reply: A's device is now sending.
    std::array<std::uint8_t, 64> heard{};
    std::size_t total = 0;
    while (total <= 8) {
        auto got = listener->read_some(heard, 5s);
        ASSERT_TRUE(got && *got > 0) << "the slow line's request and reply never went past";
        total += *got;
    }
    // No retry: a second try would outlast the slow reply and hide a wait for it.
    auto fast_reply = master_on(fast, 1s, 0)->execute(1, read_holding(0, 1));
    ASSERT_TRUE(fast_reply) << fast_reply.error().message;
    EXPECT_EQ(fast_reply->values, std::vector<std::uint16_t>{4242});
    auto slow_reply = slow_read.get();
    ASSERT_TRUE(slow_reply) << slow_reply.error().message;
    EXPECT_EQ(slow_reply->values.size(), 100U);
}

class NoHandleStream final : public transport::ByteStream {
public:
    Result<void> write(ByteView) override { return {}; }
    Result<std::size_t> read_some(std::span<std::uint8_t>, std::chrono::milliseconds) override { return std::size_t{0}; }
    void discard_input() override {}
    int poll_handle() const override { return -1; }
    std::string describe() const override { return "a stream with no handle"; }
};

TEST(SimulatedLines, RefusesAStreamItCannotWaitOn) {
    SimulatedLines lines(std::make_shared<session::LineLoop>());
    auto link = *transport::parse_link_url("rtu:virtual");
    auto added = lines.add(std::make_unique<NoHandleStream>(), std::make_unique<session::Slave>(link, session::UnitMap{}));
    ASSERT_FALSE(added);
    EXPECT_EQ(added.error().kind, ErrorKind::usage);
    EXPECT_NE(added.error().message.find("a stream with no handle"), std::string::npos) << added.error().message;
    EXPECT_EQ(lines.lines(), 0U);
}

}  // namespace
}  // namespace loopwire::simulation
