// A line's guard (link URL `guard=`, a gateway line's `guard` key): the serial master keeps at
// least that much silence after the last byte on the line before it sends, measured on the
// virtual bus's wire.
#include <gtest/gtest.h>

#include <mutex>
#include <thread>

#include "session/master.hpp"
#include "session/slave.hpp"
#include "simulation/register_bank.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::session {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// When each write began, by whom, and how many bytes: the bus starts a write when it is made
// (nothing else is on the wire here), so a write's last byte leaves its length in character
// times later.
struct WireLog {
    struct Write {
        std::string from;
        Clock::time_point at;
        std::size_t size = 0;
    };
    std::mutex mutex;
    std::vector<Write> writes;
};

// Gaps between the end of each of the slave's replies and the start of the master's next request.
std::vector<Clock::duration> gaps_after_replies(WireLog& log, std::chrono::microseconds character) {
    const std::lock_guard lock(log.mutex);
    std::vector<Clock::duration> gaps;
    for (std::size_t i = 1; i < log.writes.size(); ++i) {
        const auto& reply = log.writes[i - 1];
        const auto& request = log.writes[i];
        if (reply.from != "slave" || request.from != "master") continue;
        const auto reply_end = reply.at + character * static_cast<long long>(reply.size);
        gaps.push_back(request.at - reply_end);
    }
    return gaps;
}

std::vector<Clock::duration> measure_gaps(const std::string& link_text) {
    const auto link = *transport::parse_link_url(link_text);
    auto bus = transport::VirtualBus::create(link.serial.baud, link.serial.bits_per_character());
    auto log = std::make_shared<WireLog>();
    bus->set_fault_injector([log](const std::string& from, ByteView bytes) {
        const std::lock_guard lock(log->mutex);
        log->writes.push_back({from, Clock::now(), bytes.size()});
        return transport::BusFault{};
    });
    auto bank = std::make_shared<RegisterBank>();
    Slave slave(link, UnitMap{{1, bank}});
    auto slave_port = bus->attach("slave");
    std::jthread server([&](std::stop_token stop) { (void)slave.serve_stream(*slave_port, stop); });
    MasterOptions options;
    options.timeout = 2s;  // generous: a loaded machine may wake the slave late
    auto master = make_serial_master(bus->attach("master"), link, options);
    for (int i = 0; i < 4; ++i) {
        auto reply = master->execute(1, codec::read_request(codec::FunctionCode::read_holding_registers, 0, 2));
        EXPECT_TRUE(reply) << reply.error().message;
    }
    auto gaps = gaps_after_replies(*log, bus->character_time());
    server.request_stop();
    return gaps;
}

TEST(LineGuard, TheMasterKeepsTheGuardAfterAReplyBeforeItsNextRequest) {
    const auto gaps = measure_gaps("rtu:virtual?baud=38400&parity=none&guard=25ms");
    ASSERT_EQ(gaps.size(), 3u);
    for (const auto gap : gaps) EXPECT_GE(gap, 25ms) << std::chrono::duration_cast<std::chrono::microseconds>(gap).count() << " us";
}

// In characters: 40 characters of 10 bits at 9600 baud are 41.7 ms.
TEST(LineGuard, AGuardInCharactersCountsAtTheLinesSpeed) {
    const auto gaps = measure_gaps("rtu:virtual?baud=9600&parity=none&guard=40c");
    ASSERT_EQ(gaps.size(), 3u);
    for (const auto gap : gaps) EXPECT_GE(gap, 41666us) << std::chrono::duration_cast<std::chrono::microseconds>(gap).count() << " us";
}

}  // namespace
}  // namespace loopwire::session
