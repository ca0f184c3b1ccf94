// The Linking protocol through the session layer (ramp/soak manual, chapter 6).
#include <gtest/gtest.h>

#include <thread>

#include "codec/linking.hpp"
#include "scripted_stream.hpp"
#include "session/master.hpp"
#include "simulation/register_bank.hpp"
#include "session/slave.hpp"
#include "transport/virtual_bus.hpp"

namespace loopwire::session {
namespace {

using loopwire::testing::hex;
using loopwire::testing::ScriptedStream;
using namespace std::chrono_literals;

const transport::LinkUrl linking_link = *transport::parse_link_url("linking:/dev/null?baud=38400&parity=odd");

std::unique_ptr<Master> linking_master(ScriptedStream*& raw, std::deque<loopwire::testing::ScriptStep> script, bool ram_only = false) {
    auto stream = std::make_unique<ScriptedStream>(std::move(script));
    raw = stream.get();
    MasterOptions options;
    options.timeout = 200ms;
    options.linking_ram_only = ram_only;
    return make_serial_master(std::move(stream), linking_link, options);
}

// §6.7.1: R reads PV at 008Ah; the reply 07 4D 01 00 8A 03 E8 C3 carries 1000 (100.0).
TEST(LinkingSession, ReadExchangeOfSection6_7_1) {
    ScriptedStream* stream = nullptr;
    auto master = linking_master(stream, {{hex("52 01 00 8A 00 00 DD"), hex("07 4D 01 00 8A 03 E8 C3")}});
    auto reply = master->execute(1, codec::read_request(codec::FunctionCode::read_holding_registers, 0x8A, 1));
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(reply->values, (std::vector<std::uint16_t>{1000}));
}

// §6.7.2: M writes SV = 100 to RAM only. The manual shows no reply to M; loopwire expects the
// reply shape of §6.1 echoing address and data.
TEST(LinkingSession, RamOnlyWriteIsSentAsMOfSection6_7_2) {
    ScriptedStream* stream = nullptr;
    auto echo = codec::encode_linking_reply({1, 0, 100});
    auto master = linking_master(stream, {{hex("4D 01 00 00 00 64 B2"), echo}}, true);
    auto reply = master->execute(1, codec::write_single_register(0, 100));
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_TRUE(stream->script_done());
}

// §6.7.3: W writes SV = 1000 to RAM and EEPROM; loopwire's default for single writes.
TEST(LinkingSession, PersistentWriteIsSentAsWOfSection6_7_3) {
    ScriptedStream* stream = nullptr;
    auto echo = codec::encode_linking_reply({1, 0, 1000});
    auto master = linking_master(stream, {{hex("57 01 00 00 03 E8 43"), echo}});
    auto reply = master->execute(1, codec::write_single_register(0, 1000));
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(reply->values.at(0), 1000);
}

TEST(LinkingSession, MoreThanOneRegisterPerRequestIsAUsageError) {
    ScriptedStream* stream = nullptr;
    auto master = linking_master(stream, {});
    auto reply = master->execute(1, codec::read_request(codec::FunctionCode::read_holding_registers, 0, 2));
    ASSERT_FALSE(reply.ok());
    EXPECT_EQ(reply.error().kind, ErrorKind::usage);
    EXPECT_NE(reply.error().message.find("one register"), std::string::npos);
}

TEST(LinkingSession, SlaveServesRMAndWThroughTheWire) {
    auto bus = transport::VirtualBus::create(38400, 11);
    auto bank = std::make_shared<RegisterBank>();
    bank->set(Table::holding_registers, 0x8A, 1000);
    auto slave_port = bus->attach("slave");
    Slave slave(linking_link, {{1, bank}});
    std::jthread server([&](std::stop_token stop) { (void)slave.serve_stream(*slave_port, stop); });

    MasterOptions options;
    options.timeout = 2s;
    auto master = make_serial_master(bus->attach("master"), linking_link, options);
    auto pv = master->execute(1, codec::read_request(codec::FunctionCode::read_holding_registers, 0x8A, 1));
    ASSERT_TRUE(pv.ok()) << pv.error().message;
    EXPECT_EQ(pv->values.at(0), 1000);
    ASSERT_TRUE(master->execute(1, codec::write_single_register(0, 250)).ok());
    EXPECT_EQ(bank->get(Table::holding_registers, 0), 250);
}

}  // namespace
}  // namespace loopwire::session
