// Serial masters carried by one shared loop (MasterOptions::loop, session/line_loop.hpp): the
// same exchange as the blocking master, run as coroutines on one thread for every line. Every
// reply right, no line held by another's wait, the blocking calls still usable from other
// threads, and faults on the bus never turned into wrong values.
#include <gtest/gtest.h>

#include <condition_variable>
#include <future>
#include <mutex>
#include <memory>
#include <string>
#include <vector>

#include "session/line_loop.hpp"
#include "session/master.hpp"
#include "simulation/register_bank.hpp"
#include "simulation/simulated_lines.hpp"
#include "support/thread_names.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::session {
namespace {

using namespace std::chrono_literals;

struct Line {
    transport::LinkUrl link;
    std::shared_ptr<transport::VirtualBus> bus;
    std::shared_ptr<RegisterBank> bank = std::make_shared<RegisterBank>();
};

Line served_line(simulation::SimulatedLines& devices, std::uint32_t baud) {
    Line line;
    line.link = *transport::parse_link_url("rtu:virtual?baud=" + std::to_string(baud));
    line.bus = transport::VirtualBus::create(baud, line.link.serial.bits_per_character());
    auto added = devices.add(line.bus->attach("devices", transport::VirtualBus::Writes::return_at_once),
                             std::make_unique<Slave>(line.link, UnitMap{{1, line.bank}}));
    EXPECT_TRUE(added) << added.error().message;
    return line;
}

std::unique_ptr<Master> master_on(const Line& line, const std::shared_ptr<LineLoop>& loop,
                                  std::chrono::milliseconds timeout, unsigned retries) {
    MasterOptions options;
    options.timeout = timeout;
    options.retries = retries;
    options.loop = loop;
    return make_serial_master(line.bus->attach("master"), line.link, options);
}

codec::Request read_holding(std::uint16_t address, std::uint16_t count) {
    return codec::read_request(codec::FunctionCode::read_holding_registers, address, count);
}

// Counts answers as they come, and lets a test wait for a number of them.
class Answers {
public:
    Master::Completion expect(std::vector<std::uint16_t> values) {
        return [this, values = std::move(values)](Result<codec::Reply> reply) {
            std::lock_guard lock(mutex_);
            if (!reply) {
                ++failed_;
                last_error_ = reply.error().message;
            } else if (reply->values == values) {
                ++right_;
            } else {
                ++wrong_;
            }
            changed_.notify_all();
        };
    }
    // Until `count` have come, for at most 60 s: whether they did.
    bool wait_for(int count) {
        std::unique_lock lock(mutex_);
        return changed_.wait_for(lock, 60s, [&] { return right_ + wrong_ + failed_ >= count; });
    }
    int right() const { std::lock_guard lock(mutex_); return right_; }
    int wrong() const { std::lock_guard lock(mutex_); return wrong_; }
    int failed() const { std::lock_guard lock(mutex_); return failed_; }
    std::string last_error() const { std::lock_guard lock(mutex_); return last_error_; }

private:
    mutable std::mutex mutex_;
    std::condition_variable changed_;
    int right_ = 0;
    int wrong_ = 0;
    int failed_ = 0;
    std::string last_error_;
};

TEST(SerialMastersOnALoop, FourLinesAreCarriedByOneThreadEveryReplyRight) {
    auto loop = std::make_shared<LineLoop>();
    simulation::SimulatedLines devices(loop);  // the devices answer from the masters' loop too
    std::vector<Line> lines;
    std::vector<std::unique_ptr<Master>> masters;
    for (std::uint16_t i = 0; i < 4; ++i) {
        lines.push_back(served_line(devices, 19200));
        lines.back().bank->set(codec::Table::holding_registers, 10, static_cast<std::uint16_t>(100 + i));
        masters.push_back(master_on(lines.back(), loop, 2s, 2));
    }
    Answers answers;
    // Every request of every line queued at once: the loop carries them one at a time per line.
    for (std::uint16_t i = 0; i < 4; ++i) {
        for (int n = 0; n < 20; ++n) {
            masters[i]->execute_async(1, read_holding(10, 1), answers.expect({static_cast<std::uint16_t>(100 + i)}));
        }
    }
    ASSERT_TRUE(answers.wait_for(80)) << "not every request was answered in 60 s";
    EXPECT_EQ(answers.right(), 80) << answers.last_error();
    EXPECT_EQ(answers.wrong(), 0);
    const auto names = testing::thread_names();
    EXPECT_EQ(names.count("lw-lines"), 1U);
    EXPECT_EQ(names.count("lw-serial"), 0U) << "a master on the loop started a thread of its own";
}

// Line A waits out a 3 s timeout (nobody is unit 9); meanwhile line B, on the same loop, is
// asked and answered. A loop that waited for A would answer B after A's timeout.
TEST(SerialMastersOnALoop, ALineWaitingOutATimeoutHoldsNoOtherLine) {
    auto loop = std::make_shared<LineLoop>();
    simulation::SimulatedLines devices(loop);  // the devices answer from the masters' loop too
    Line a = served_line(devices, 19200);
    Line b = served_line(devices, 19200);
    b.bank->set(codec::Table::holding_registers, 0, 4242);
    auto master_a = master_on(a, loop, 3s, 0);
    auto master_b = master_on(b, loop, 2s, 2);
    std::promise<Result<codec::Reply>> a_done;
    master_a->execute_async(9, read_holding(0, 1), [&a_done](Result<codec::Reply> reply) { a_done.set_value(std::move(reply)); });
    auto b_reply = master_b->execute(1, read_holding(0, 1));
    auto a_reply = a_done.get_future();
    EXPECT_EQ(a_reply.wait_for(0s), std::future_status::timeout) << "line A's timeout ended before line B was answered";
    ASSERT_TRUE(b_reply) << b_reply.error().message;
    EXPECT_EQ(b_reply->values, std::vector<std::uint16_t>{4242});
    ASSERT_EQ(a_reply.wait_for(60s), std::future_status::ready);
    auto a_result = a_reply.get();
    ASSERT_FALSE(a_result);
    EXPECT_EQ(a_result.error().kind, ErrorKind::timeout) << a_result.error().message;
}

// A blocking call from the loop's own thread (inside a completion) could never end: refused.
TEST(SerialMastersOnALoop, ABlockingCallOnTheLoopItselfIsRefused) {
    auto loop = std::make_shared<LineLoop>();
    simulation::SimulatedLines devices(loop);  // the devices answer from the masters' loop too
    Line line = served_line(devices, 115200);
    auto master = master_on(line, loop, 2s, 2);
    std::promise<Result<codec::Reply>> inner;
    master->execute_async(1, read_holding(0, 1), [&](Result<codec::Reply>) { inner.set_value(master->execute(1, read_holding(0, 1))); });
    auto future = inner.get_future();
    ASSERT_EQ(future.wait_for(60s), std::future_status::ready);
    auto refused = future.get();
    ASSERT_FALSE(refused);
    EXPECT_EQ(refused.error().kind, ErrorKind::usage);
    EXPECT_NE(refused.error().message.find("would never end"), std::string::npos) << refused.error().message;
}

// A master destroyed with requests still queued ends each of them: every completion runs, with
// the right value (what was carried before the destruction reached the loop) or the closing
// error, never a wrong value and never lost.
TEST(SerialMastersOnALoop, DestroyingAMasterEndsWhatWasQueued) {
    auto loop = std::make_shared<LineLoop>();
    simulation::SimulatedLines devices(loop);  // the devices answer from the masters' loop too
    Line line = served_line(devices, 115200);
    line.bank->set(codec::Table::holding_registers, 3, 77);
    auto master = master_on(line, loop, 2s, 2);
    Answers answers;
    for (int n = 0; n < 5; ++n) master->execute_async(1, read_holding(3, 1), answers.expect({77}));
    master.reset();
    EXPECT_EQ(answers.right() + answers.failed(), 5);
    EXPECT_EQ(answers.wrong(), 0);
    if (answers.failed() > 0) {
        EXPECT_NE(answers.last_error().find("the line is being closed"), std::string::npos) << answers.last_error();
    }
}

// A master destroyed while it waits for a reply that will not come (nobody is unit 9, the
// timeout a minute) does not wait the timeout out: the request ends at once with the closing
// error, not a timeout (a gateway told to stop held its SIGTERM for the rest of a 20 s timeout).
TEST(SerialMastersOnALoop, DestroyingAMasterEndsTheWaitUnderWay) {
    auto loop = std::make_shared<LineLoop>();
    simulation::SimulatedLines devices(loop);
    Line line = served_line(devices, 115200);
    line.bank->set(codec::Table::holding_registers, 3, 77);
    auto master = master_on(line, loop, 60s, 0);
    ASSERT_TRUE(master->execute(1, read_holding(3, 1)).ok());  // the line works
    std::promise<Result<codec::Reply>> ended;
    master->execute_async(9, read_holding(3, 1), [&ended](Result<codec::Reply> reply) { ended.set_value(std::move(reply)); });
    master.reset();
    auto reply = ended.get_future();
    ASSERT_EQ(reply.wait_for(0s), std::future_status::ready) << "the destruction returned before the request ended";
    const auto result = reply.get();
    ASSERT_FALSE(result.ok());
    EXPECT_EQ(result.error().kind, ErrorKind::link) << result.error().message;
    EXPECT_NE(result.error().message.find("the line is being closed"), std::string::npos) << result.error().message;
}

// Every reply comes twice, the copy 25 ms after the first: on a loop as on a thread, a copy is
// never taken for the next request's reply. Registers r hold 1000 + r, so a value taken from
// another request's reply shows.
TEST(SerialMastersOnALoop, CopiedRepliesNeverBecomeWrongValues) {
    auto loop = std::make_shared<LineLoop>();
    simulation::SimulatedLines devices(loop);  // the devices answer from the masters' loop too
    Line line = served_line(devices, 38400);
    for (std::uint16_t r = 0; r < 8; ++r) line.bank->set(codec::Table::holding_registers, r, static_cast<std::uint16_t>(1000 + r));
    line.bus->set_fault_injector([](const std::string& from, ByteView) {
        transport::BusFault fault;
        if (from == "devices") fault.duplicate_after = std::chrono::microseconds(25'000);
        return fault;
    });
    auto master = master_on(line, loop, 500ms, 2);
    Answers answers;
    for (int n = 0; n < 40; ++n) {
        const auto r = static_cast<std::uint16_t>(n % 8);
        master->execute_async(1, read_holding(r, 1), answers.expect({static_cast<std::uint16_t>(1000 + r)}));
    }
    ASSERT_TRUE(answers.wait_for(40)) << "not every request ended in 60 s";
    EXPECT_EQ(answers.wrong(), 0);
    EXPECT_GT(answers.right(), 20) << answers.last_error();
}

}  // namespace
}  // namespace loopwire::session
