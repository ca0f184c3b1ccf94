// Slave dispatch and the silence rules, through the wire on the virtual bus (docs/DESIGN.md: encode
// a request, feed the slave, decode the reply).
#include <gtest/gtest.h>

#include <deque>
#include <thread>

#include "codec/rtu.hpp"
#include "scripted_stream.hpp"
#include "support/virtual_line.hpp"
#include "session/master.hpp"
#include "simulation/register_bank.hpp"
#include "session/slave.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::session {
namespace {

using loopwire::testing::hex;
using loopwire::testing::VirtualLine;
using namespace std::chrono_literals;

const transport::LinkUrl rtu_link = *transport::parse_link_url("rtu:virtual?baud=38400&parity=none");

class SlaveOnBus : public ::testing::Test {
protected:
    void SetUp() override {
        bus = transport::VirtualBus::create(38400, 10);
        slave_port = bus->attach("slave");
        slave = std::make_unique<Slave>(rtu_link, UnitMap{{1, unit1}, {2, unit2}});
        server = std::jthread([this](std::stop_token stop) { (void)slave->serve_stream(*slave_port, stop); });
        probe = bus->attach("probe");
    }
    void TearDown() override {
        server.request_stop();
        server.join();
    }

    // Writes raw bytes and collects what comes back: everything up to 30 ms of quiet after the
    // first byte, or nothing within `wait` (generous, for loaded machines; silence tests pay it).
    Bytes exchange(const Bytes& frame, std::chrono::milliseconds wait = 400ms) {
        EXPECT_TRUE(probe->write(frame).ok());
        Bytes got;
        std::array<std::uint8_t, 256> buffer{};
        const auto until = std::chrono::steady_clock::now() + wait;
        while (std::chrono::steady_clock::now() < until) {
            auto n = probe->read_some(buffer, got.empty() ? 10ms : 30ms);
            if (!n.ok()) break;
            if (*n == 0 && !got.empty()) break;
            got.insert(got.end(), buffer.begin(), buffer.begin() + static_cast<long>(*n));
        }
        return got;
    }

    std::shared_ptr<transport::VirtualBus> bus;
    std::unique_ptr<transport::ByteStream> slave_port;
    std::unique_ptr<transport::ByteStream> probe;
    std::shared_ptr<RegisterBank> unit1 = std::make_shared<RegisterBank>();
    std::shared_ptr<RegisterBank> unit2 = std::make_shared<RegisterBank>();
    std::unique_ptr<Slave> slave;
    std::jthread server;
};

TEST_F(SlaveOnBus, AnswersAReadWithTheBanksValues) {
    unit1->set(Table::holding_registers, 0x8A, 1000);
    // Ramp/soak manual §4.7.1 request and reply.
    EXPECT_EQ(to_hex(exchange(hex("01 03 00 8A 00 01 A5 E0"))), "01 03 02 03 E8 B8 FA");
}

TEST_F(SlaveOnBus, EchoesWritesAndStoresThem) {
    // Ramp/soak manual §4.7.3: FC16 writes 100 and 1000 to registers 0 and 1.
    EXPECT_EQ(to_hex(exchange(hex("01 10 00 00 00 02 04 00 64 03 E8 B2 CE"))), "01 10 00 00 00 02 41 C8");
    EXPECT_EQ(unit1->get(Table::holding_registers, 0), 100);
    EXPECT_EQ(unit1->get(Table::holding_registers, 1), 1000);
}

TEST_F(SlaveOnBus, BadCrcGetsNoReply) {
    EXPECT_TRUE(exchange(hex("01 03 00 8A 00 01 A5 E1")).empty());
}


TEST_F(SlaveOnBus, BadQuantityGetsIllegalDataValue) {
    EXPECT_EQ(to_hex(exchange(codec::rtu_encode(1, hex("03 00 00 00 7E")))), to_hex(codec::rtu_encode(1, hex("83 03"))));
}

TEST_F(SlaveOnBus, RangePastTheLastAddressGetsIllegalDataAddress) {
    EXPECT_EQ(to_hex(exchange(codec::rtu_encode(1, hex("03 FF FF 00 02")))), to_hex(codec::rtu_encode(1, hex("83 02"))));
}

TEST_F(SlaveOnBus, NoiseBeforeARequestDoesNotStopTheAnswer) {
    unit1->set(Table::holding_registers, 0x8A, 7);
    Bytes noisy = hex("FF 00 13");
    const Bytes request = hex("01 03 00 8A 00 01 A5 E0");
    noisy.insert(noisy.end(), request.begin(), request.end());
    EXPECT_EQ(to_hex(exchange(noisy)), to_hex(codec::rtu_encode(1, hex("03 02 00 07"))));
}

TEST_F(SlaveOnBus, MasterAndSlaveAgreeOnEveryFunction) {
    MasterOptions options;
    options.timeout = 2s;
    auto master = make_serial_master(bus->attach("master"), rtu_link, options);
    ASSERT_TRUE(master->execute(2, codec::write_multiple_coils(10, {1, 0, 1, 1})).ok());
    ASSERT_TRUE(master->execute(2, codec::write_single_coil(14, true)).ok());
    auto coils = master->execute(2, codec::read_request(codec::FunctionCode::read_coils, 10, 5));
    ASSERT_TRUE(coils.ok()) << coils.error().message;
    EXPECT_EQ(coils->values, (std::vector<std::uint16_t>{1, 0, 1, 1, 1}));
    unit2->set(Table::discrete_inputs, 3, 1);
    unit2->set(Table::input_registers, 3, 0xBEEF);
    auto inputs = master->execute(2, codec::read_request(codec::FunctionCode::read_discrete_inputs, 2, 3));
    ASSERT_TRUE(inputs.ok());
    EXPECT_EQ(inputs->values, (std::vector<std::uint16_t>{0, 1, 0}));
    auto registers = master->execute(2, codec::read_request(codec::FunctionCode::read_input_registers, 3, 1));
    ASSERT_TRUE(registers.ok());
    EXPECT_EQ(registers->values.at(0), 0xBEEF);
    EXPECT_EQ(unit1->get(Table::coils, 10), 0);  // unit 1 untouched
}

TEST_F(SlaveOnBus, SeveralThreadsShareOneMasterOnAMultiDropLine) {
    MasterOptions options;
    options.timeout = 2s;
    auto master = make_serial_master(bus->attach("master"), rtu_link, options);
    std::vector<std::thread> threads;
    std::atomic<int> good{0};
    for (std::uint16_t t = 0; t < 4; ++t) {
        threads.emplace_back([&, t] {
            for (std::uint16_t i = 0; i < 5; ++i) {
                const auto unit = static_cast<std::uint8_t>(1 + (t % 2));
                const auto address = static_cast<std::uint16_t>(t * 10 + i);
                if (!master->execute(unit, codec::write_single_register(address, address + 1000)).ok()) continue;
                auto back = master->execute(unit, codec::read_request(codec::FunctionCode::read_holding_registers, address, 1));
                if (back.ok() && back->values.at(0) == address + 1000) ++good;
            }
        });
    }
    for (auto& t : threads) t.join();
    EXPECT_EQ(good.load(), 20);
}

// RTU at 9600 baud, 8N1: 3.5 characters are 3.5 * 10 / 9600 s, about 3.6 ms.
class SlaveInVirtualTime : public ::testing::Test {
protected:
    // Serves every request given, each arriving `spacing` after the one before, until the line
    // is done; returns what the slave wrote.
    const std::vector<VirtualLine::Write>& serve(const std::vector<Bytes>& requests,
                                                 std::chrono::milliseconds spacing = 500ms) {
        Instant at = clock->now();
        for (const auto& request : requests) line.arrive(at += spacing, request);
        SlaveOptions options;
        options.clock = clock;
        Slave slave(link, UnitMap{{1, unit1}, {2, unit2}}, options);
        EXPECT_TRUE(slave.serve_stream(line, stop.get_token()).ok());
        return line.writes();
    }

    const transport::LinkUrl link = *transport::parse_link_url("rtu:virtual?baud=9600&parity=none");
    std::shared_ptr<VirtualClock> clock = std::make_shared<VirtualClock>();
    std::stop_source stop;
    VirtualLine line{clock, stop};
    std::shared_ptr<RegisterBank> unit1 = std::make_shared<RegisterBank>();
    std::shared_ptr<RegisterBank> unit2 = std::make_shared<RegisterBank>();
};

// Modbus over serial line V1.02, 2.5.1.1: the request ends with 3.5 characters of silence, and
// only then may the reply start. The frame is complete by its length when its last byte comes,
// so the slave waits out exactly the gap.
TEST_F(SlaveInVirtualTime, RepliesExactlyThreeAndAHalfCharactersAfterTheRequest) {
    unit1->set(Table::holding_registers, 0x8A, 1000);
    const Instant start = clock->now();
    const auto& writes = serve({hex("01 03 00 8A 00 01 A5 E0")});  // ramp/soak manual §4.7.1
    ASSERT_EQ(writes.size(), 1u);
    EXPECT_EQ(to_hex(writes[0].bytes), "01 03 02 03 E8 B8 FA");
    EXPECT_EQ(writes[0].at - start, (500ms + codec::CharacterTiming{9600, 10}.t3_5()));
}

// A function the RTU framer cannot size ends only at the 3.5-character silence after it, which
// the slave waits through itself. In virtual time: on the wall clock's virtual bus a loaded host
// that wakes the slave's reader late splits such a frame at a silence the wire never had.
TEST_F(SlaveInVirtualTime, UnknownFunctionGetsIllegalFunction) {
    const auto& writes = serve({codec::rtu_encode(2, hex("2B 0E 01 00"))});
    ASSERT_EQ(writes.size(), 1u);
    EXPECT_EQ(to_hex(writes[0].bytes), to_hex(codec::rtu_encode(2, hex("AB 01"))));
}

// Silence is checked to the end of the line, not for a window of wall time.
TEST_F(SlaveInVirtualTime, AnotherUnitsRequestGetsNoReply) {
    EXPECT_TRUE(serve({codec::rtu_encode(9, hex("03 00 00 00 01"))}).empty());
}

TEST_F(SlaveInVirtualTime, BroadcastIsExecutedByEveryUnitAndNotAnswered) {
    EXPECT_TRUE(serve({codec::rtu_encode(0, hex("06 00 05 12 34"))}).empty());
    EXPECT_EQ(unit1->get(Table::holding_registers, 5), 0x1234);
    EXPECT_EQ(unit2->get(Table::holding_registers, 5), 0x1234);
}

// A broadcast between two requests leaves the unit asked next answering as usual.
TEST_F(SlaveInVirtualTime, AnswersOnlyTheRequestsAddressedToItsUnits) {
    const auto& writes = serve({codec::rtu_encode(9, hex("03 00 00 00 01")), codec::rtu_encode(0, hex("06 00 05 12 34")),
                                codec::rtu_encode(2, hex("03 00 05 00 01"))});
    ASSERT_EQ(writes.size(), 1u);
    EXPECT_EQ(to_hex(writes[0].bytes), to_hex(codec::rtu_encode(2, hex("03 02 12 34"))));
}

}  // namespace
}  // namespace loopwire::session
