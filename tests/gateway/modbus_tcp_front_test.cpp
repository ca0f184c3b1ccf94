// The Modbus TCP front on its own: one client connection kept while the units behind it are
// replaced, as across a reload that reopens the gateway (gateway/modbus_tcp_front.hpp).
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "gateway/modbus_tcp_front.hpp"
#include "session/tcp_test_client.hpp"
#include "support/test_bytes.hpp"

namespace loopwire::gateway {
namespace {

using loopwire::testing::hex;
using session::testing::RawClient;
using namespace std::chrono_literals;

// A unit that answers every read of one register with `value`.
class FixedUnit final : public session::UnitHandler {
public:
    explicit FixedUnit(std::uint8_t value) : value_(value) {}
    std::optional<Bytes> handle(ByteView request_pdu, bool broadcast) override {
        if (broadcast) return std::nullopt;
        return Bytes{request_pdu[0], 0x02, 0x00, value_};
    }

private:
    std::uint8_t value_;
};

ModbusTcpConfig loopback() {
    ModbusTcpConfig config;
    config.port = 0;
    return config;
}

// Transaction `id`, unit 3, read holding register 0 (function 3, quantity 1).
Bytes read_request(std::uint8_t id) { return Bytes{0x00, id, 0x00, 0x00, 0x00, 0x06, 0x03, 0x03, 0x00, 0x00, 0x00, 0x01}; }

TEST(ModbusTcpFront, KeepsAConnectionWhileItsUnitsAreHeldAndReplaced) {
    auto opened = ModbusTcpFront::open(loopback());
    ASSERT_TRUE(opened) << opened.error().message;
    ModbusTcpFront& front = **opened;
    RawClient client(front.port());
    ASSERT_TRUE(client.connected());

    // Before any gateway routes to it: no path to the unit (exception 0Ah).
    ASSERT_TRUE(client.send(read_request(1)));
    EXPECT_EQ(client.receive(9), hex("00 01 00 00 00 03 03 83 0A"));

    session::UnitMap first{{3, std::make_shared<FixedUnit>(0x11)}};
    front.route_to(first);
    ASSERT_TRUE(client.send(read_request(2)));
    EXPECT_EQ(client.receive(11), hex("00 02 00 00 00 05 03 03 02 00 11"));

    // Between two gateways: the unit's requests are answered at once with exception 0Bh.
    front.hold(first);
    ASSERT_TRUE(client.send(read_request(3)));
    EXPECT_EQ(client.receive(9), hex("00 03 00 00 00 03 03 83 0B"));

    front.route_to({{3, std::make_shared<FixedUnit>(0x22)}});
    ASSERT_TRUE(client.send(read_request(4)));
    EXPECT_EQ(client.receive(11), hex("00 04 00 00 00 05 03 03 02 00 22"));

    const auto statistics = front.statistics();
    EXPECT_EQ(statistics.accepted, 1u);
    EXPECT_EQ(statistics.open, 1u);
    EXPECT_FALSE(front.failed().stop_requested());
}

TEST(ModbusTcpFront, ListensAsOnlyTheSameAddressAndLimits) {
    auto opened = ModbusTcpFront::open(loopback());
    ASSERT_TRUE(opened) << opened.error().message;
    ModbusTcpConfig same = loopback();
    same.writes = false;  // the units' business, not the listener's
    same.max_age = 500ms;
    EXPECT_TRUE((*opened)->listens_as(same));
    ModbusTcpConfig fewer = loopback();
    fewer.max_connections = 8;
    EXPECT_FALSE((*opened)->listens_as(fewer));
    ModbusTcpConfig elsewhere = loopback();
    elsewhere.port = 1502;
    EXPECT_FALSE((*opened)->listens_as(elsewhere));
    ModbusTcpConfig disabled = loopback();
    disabled.enabled = false;
    EXPECT_FALSE((*opened)->listens_as(disabled));
}

TEST(ModbusTcpFront, AnAddressInUseIsAClearError) {
    auto first = ModbusTcpFront::open(loopback());
    ASSERT_TRUE(first) << first.error().message;
    ModbusTcpConfig taken = loopback();
    taken.port = (*first)->port();
    auto second = ModbusTcpFront::open(taken);
    ASSERT_FALSE(second);
    EXPECT_NE(second.error().message.find("modbus_tcp.listen 127.0.0.1:" + std::to_string(taken.port)), std::string::npos)
        << second.error().message;
}

}  // namespace
}  // namespace loopwire::gateway
